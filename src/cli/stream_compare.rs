//! `stripmask stream-compare`: whole-tile belts against progressive tiles.

use std::path::PathBuf;

use clap::Args;
use stripmask::Named;
use stripmask::error::Result;
use stripmask::sim::device::DeviceProfile;
use stripmask::sim::flight::Builtin;
use stripmask::sim::stream_compare::{self as compare, CompareOptions, LINKS};

use super::args::{named, positive, profile_name};

/// `stream-compare`'s arguments: the archive, the flights, their length and the device.
#[derive(Args, Debug)]
pub(super) struct StreamCompareArgs {
    /// An archive file or http:// URL.
    source: String,
    /// Output folder: stream-compare.md and stream-compare.csv.
    #[arg(long, default_value = "stripmask-stream")]
    out: PathBuf,
    /// The flights, comma-separated (default: every built-in one).
    #[arg(long, value_parser = named::<Builtin>(), value_delimiter = ',')]
    flights: Option<Vec<Builtin>>,
    /// Seconds of each flight (default: all of it).
    #[arg(long, allow_negative_numbers = true)]
    seconds: Option<f64>,
    /// Device profile (its link is replaced by each link).
    #[arg(long, value_parser = profile_name(), default_value_t = DeviceProfile::pocketpc().name)]
    profile: String,
    /// No progress bar.
    #[arg(short, long)]
    quiet: bool,
}

/// Runs the comparison and prints where its table went.
pub(super) fn run(a: StreamCompareArgs) -> Result<()> {
    if let Some(s) = a.seconds {
        positive("--seconds", s)?;
    }
    let options = CompareOptions {
        source: a.source,
        flights: a.flights.unwrap_or_else(Builtin::all),
        links: LINKS.to_vec(),
        seconds: a.seconds,
        profile: DeviceProfile::named(&a.profile)?,
        out: a.out.clone(),
        progress: !a.quiet,
    };
    let results = compare::compare(&options)?;
    say!("{}", compare::write(&a.out, &results, &options)?);
    Ok(())
}
