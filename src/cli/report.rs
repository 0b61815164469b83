//! `stripmask report`: the plots of a flight's statistics.

use std::path::PathBuf;

use clap::Args;
use stripmask::error::Result;

/// `report`'s argument: the folder of a flight.
#[derive(Args, Debug)]
pub(super) struct ReportArgs {
    /// A folder holding stats.csv (what `fly` or `demo` wrote).
    dir: PathBuf,
}

/// Draws the plots and prints their paths.
pub(super) fn run(a: ReportArgs) -> Result<()> {
    for path in stripmask::sim::report::draw(&a.dir)? {
        say!("{}", path.display());
    }
    Ok(())
}
