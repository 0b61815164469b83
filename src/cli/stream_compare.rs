//! `stripmask stream-compare`: whole-tile belts against progressive tiles.

use std::path::PathBuf;

use clap::Args;
use stripmask::error::Result;
use stripmask::sim::device::{DeviceProfile, Overrides};
use stripmask::sim::flight::Builtin;

use super::args::positive;

#[derive(Args, Debug)]
pub(super) struct StreamCompareArgs {
    /// An archive file or http:// URL.
    pub(super) source: String,
    /// Output folder: stream-compare.md and stream-compare.csv.
    #[arg(long, default_value = "stripmask-stream")]
    pub(super) out: PathBuf,
    /// The flights, comma-separated (default: every built-in one).
    #[arg(long, value_enum, value_delimiter = ',')]
    pub(super) flights: Option<Vec<Builtin>>,
    /// Seconds of each flight (default: all of it).
    #[arg(long)]
    pub(super) seconds: Option<f64>,
    /// Device profile: pocketpc, workstation or native (its link is replaced by each link).
    #[arg(long, default_value = "pocketpc")]
    pub(super) profile: String,
    /// No progress bar.
    #[arg(short, long)]
    pub(super) quiet: bool,
}

pub(super) fn run(a: StreamCompareArgs) -> Result<()> {
    use stripmask::sim::stream_compare::{self as compare, CompareOptions, LINKS};
    if let Some(s) = a.seconds {
        positive("--seconds", s)?;
    }
    let options = CompareOptions {
        source: a.source,
        flights: a
            .flights
            .unwrap_or_else(|| vec![Builtin::Overview, Builtin::Diagonal, Builtin::Low]),
        links: LINKS.to_vec(),
        seconds: a.seconds,
        profile: DeviceProfile::resolve(&a.profile, None, &Overrides::default())?,
        out: a.out.clone(),
        progress: !a.quiet,
    };
    let results = compare::compare(&options)?;
    println!("{}", compare::write(&a.out, &results, &options)?);
    Ok(())
}
