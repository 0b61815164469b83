//! `stripmask tradeoff`: every speed-for-accuracy knob measured against the references.

use std::path::PathBuf;

use clap::Args;
use clap::builder::PossibleValuesParser;
use stripmask::engine::allocation::Allocation;
use stripmask::error::Result;
use stripmask::sim::tradeoff::reference::{CpuFloat, Reference};
use stripmask::sim::tradeoff::{TradeoffOptions, knobs, run_with};
use stripmask::{ErrorBound, Named};

use super::args::{flight, named, parse_size};

/// `tradeoff`'s arguments: the archive, the views, the frame size, the repeats and the knobs.
#[derive(Args, Debug)]
pub(super) struct TradeoffArgs {
    /// An archive file or http:// URL.
    source: String,
    /// Output folder: tradeoff.md, tradeoff.csv, pareto.png and the reference pictures.
    #[arg(long, default_value = "stripmask-tradeoff")]
    out: PathBuf,
    /// Also views along this flight: a built-in one (overview, diagonal, low) or a TOML file.
    #[arg(long)]
    flight: Option<String>,
    /// Views taken from --flight, evenly spaced in time.
    #[arg(long, default_value_t = 3)]
    flight_views: usize,
    /// Use only the first N built-in views (overview, oblique, low, horizon, down).
    #[arg(long)]
    views: Option<usize>,
    /// Frame size.
    #[arg(long, value_parser = parse_size, default_value = "320x240")]
    size: (u32, u32),
    /// Timed frames per setting and view (the median counts).
    #[arg(long, default_value_t = 5)]
    repeats: usize,
    /// A pixel is off when a channel differs from the reference by more than this.
    #[arg(long, default_value_t = 16)]
    threshold: u8,
    /// The pixel-error bound τ of the defaults, pixels (0: off); the max-error knob turns it.
    #[arg(long, default_value_t = ErrorBound::DEFAULT_PIXELS)]
    max_error_px: f64,
    /// How the defaults share the triangle budget (importance or error); the allocation knob
    /// turns it.
    #[arg(long, value_parser = named::<Allocation>(), default_value = Allocation::default().name())]
    allocation: Allocation,
    /// Turn only these knobs, comma-separated.
    #[arg(long, value_delimiter = ',', value_parser = knob_name())]
    knobs: Option<Vec<String>>,
    /// No line per setting on stderr.
    #[arg(short, long)]
    quiet: bool,
}

/// Parses the name of one of the sweep's knobs.
fn knob_name() -> PossibleValuesParser {
    PossibleValuesParser::new(knobs::knobs().into_iter().map(|k| k.name))
}

/// Runs the sweep and prints how many settings it measured and where the table went.
pub(super) fn run(a: TradeoffArgs) -> Result<()> {
    let flight = match &a.flight {
        Some(name) => Some(flight(name, &a.source)?),
        None => None,
    };
    let options = TradeoffOptions {
        source: a.source,
        out: a.out.clone(),
        flight,
        flight_views: a.flight_views,
        builtin_views: a.views,
        size: a.size,
        repeats: a.repeats,
        threshold: a.threshold,
        knobs: a.knobs,
        max_error: ErrorBound::from_pixels("--max-error-px", a.max_error_px)?,
        allocation: a.allocation,
        progress: !a.quiet,
    };
    let report = run_with(&options, references(a.size))?;
    let front = report.rows.iter().filter(|r| r.pareto).count();
    say!(
        "{} settings over {} views, {} on the Pareto front -> {}",
        report.rows.len(),
        report.views.len(),
        front,
        a.out.join("tradeoff.md").display()
    );
    Ok(())
}

/// The CPU float reference, and with the `wgpu` feature the GPU one where an adapter exists
/// (where none does, the report says why and goes on with the CPU reference).
#[cfg_attr(not(feature = "wgpu"), allow(unused_variables))]
fn references(size: (u32, u32)) -> Vec<Box<dyn Reference>> {
    #[cfg_attr(not(feature = "wgpu"), allow(unused_mut))]
    let mut references: Vec<Box<dyn Reference>> = vec![Box::new(CpuFloat)];
    #[cfg(feature = "wgpu")]
    match stripmask::sim::tradeoff::reference::Gpu::new(size) {
        Ok(gpu) => {
            eprintln!("wgpu reference on {}", gpu.adapter());
            references.push(Box::new(gpu));
        }
        Err(e) => eprintln!("wgpu reference skipped: {e}"),
    }
    references
}
