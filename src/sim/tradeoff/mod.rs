//! `stripmask tradeoff`: what each speed-for-accuracy knob costs and what it buys.
//!
//! Over a fixed set of `views` (plus views sampled from a flight), the `sweep` turns the
//! [`knobs`] one at a time and in the combinations that interact; for each setting
//! `measure` times whole engine frames (every tile loaded, so only rendering is timed) and
//! compares the pictures with each [`mod@reference`] ([`metrics`]: PSNR, SSIM, pixels off), and
//! computes the screen-space geometric error of the masks the budget chose. `output` writes
//! a Markdown table, a CSV and the error-against-time plot with its Pareto front ([`plot`]).

pub mod knobs;
mod measure;
pub mod metrics;
mod output;
pub mod plot;
pub mod reference;
mod sweep;
mod views;

use std::path::PathBuf;

use crate::db::archive::ArchiveReader;
use crate::db::source;
use crate::engine::allocation::Allocation;
use crate::engine::error_bound::ErrorBound;
use crate::engine::terrain::TerrainFrame;
use crate::error::{Error, Result};
use crate::sim::flight::Flight;
use knobs::Setting;
use measure::{Bench, Measurement};
use reference::Reference;
use sweep::Entry;
use views::Viewpoint;

/// What a run measures and where it writes.
pub struct TradeoffOptions {
    /// The archive, a file or http:// URL.
    pub source: String,
    /// Output folder: `tradeoff.md`, `tradeoff.csv`, `pareto.png`, reference pictures.
    pub out: PathBuf,
    /// Views sampled along this flight join the built-in ones.
    pub flight: Option<Flight>,
    /// How many views to take from the flight.
    pub flight_views: usize,
    /// Keep only the first this many built-in views (`None`: all).
    pub builtin_views: Option<usize>,
    /// Frame size, pixels.
    pub size: (u32, u32),
    /// Timed frames per setting and view; the median is reported.
    pub repeats: usize,
    /// A pixel is off when a channel differs from the reference by more than this.
    pub threshold: u8,
    /// Turn only these knobs (`None`: all).
    pub knobs: Option<Vec<String>>,
    /// The pixel-error bound τ of the defaults (every setting but the `max-error` knob's).
    pub max_error: ErrorBound,
    /// How the defaults share the triangle budget (every setting but the `allocation` knob's).
    pub allocation: Allocation,
    /// Print a line per setting measured.
    pub progress: bool,
}

/// One measured setting.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    /// The setting.
    pub entry: Entry,
    /// What it measured.
    pub measurement: Measurement,
    /// Frame time over the defaults' frame time, same run.
    pub ratio: f64,
    /// No other setting is both at least as fast and at least as accurate (by 1 - SSIM against
    /// the first reference), and better in one.
    pub pareto: bool,
}

/// A run's results.
#[derive(Clone, Debug, PartialEq)]
pub struct TradeoffReport {
    /// The archive measured.
    pub source: String,
    /// The views, in order.
    pub views: Vec<Viewpoint>,
    /// Reference names, in the order of each measurement's errors.
    pub references: Vec<String>,
    /// Frame size.
    pub size: (u32, u32),
    /// Timed frames per setting and view.
    pub repeats: usize,
    /// The pixels-off threshold.
    pub threshold: u8,
    /// The settings, defaults first.
    pub rows: Vec<Row>,
}

/// Runs the sweep with the CPU float reference and writes the outputs; returns the results.
pub fn run(options: &TradeoffOptions) -> Result<TradeoffReport> {
    run_with(options, vec![Box::new(reference::CpuFloat)])
}

/// Runs the sweep against `references` (the first one decides the Pareto front and the plot)
/// and writes the outputs.
pub fn run_with(
    options: &TradeoffOptions,
    mut references: Vec<Box<dyn Reference>>,
) -> Result<TradeoffReport> {
    if references.is_empty() {
        return Err(Error::setting("tradeoff references", 0, "at least one"));
    }
    let terrain = TerrainFrame::new(ArchiveReader::open(source::open(&options.source)?)?.header());
    let mut views = views::builtin(&terrain);
    views.truncate(options.builtin_views.unwrap_or(views.len()));
    if let Some(flight) = &options.flight {
        views.extend(views::from_flight(flight, options.flight_views));
    }
    if views.is_empty() {
        return Err(Error::setting(
            "tradeoff views",
            0,
            "at least one: keep some built-in views or add a flight's",
        ));
    }
    let all_knobs = knobs::knobs();
    if let Some(only) = &options.knobs {
        for name in only {
            if !all_knobs.iter().any(|k| k.name == name) {
                let names: Vec<_> = all_knobs.iter().map(|k| k.name).collect();
                return Err(Error::setting(
                    "--knobs",
                    format!("{name:?}"),
                    format!("knobs among {}", names.join(", ")),
                ));
            }
        }
    }
    let defaults = Setting {
        max_error: options.max_error,
        allocation: options.allocation,
        ..Setting::default()
    };
    let entries = sweep::plan(&all_knobs, options.knobs.as_deref(), defaults);

    let mut bench = Bench::new(&options.source, options.size, views)?;
    let progress = |view: &Viewpoint| {
        if options.progress {
            eprintln!("view {}: {} settings", view.name, entries.len());
        }
    };
    let (measurements, images) = bench.measure(
        &entries,
        options.repeats,
        &mut references,
        options.threshold,
        &progress,
    )?;
    let base = measurements[0].frame_seconds.max(1e-12);
    let error = |m: &Measurement| 1.0 - m.errors[0].ssim;
    let rows = entries
        .into_iter()
        .zip(&measurements)
        .map(|(entry, m)| Row {
            entry,
            measurement: m.clone(),
            ratio: m.frame_seconds / base,
            pareto: !measurements.iter().any(|o| {
                o.frame_seconds <= m.frame_seconds
                    && error(o) <= error(m)
                    && (o.frame_seconds < m.frame_seconds || error(o) < error(m))
            }),
        })
        .collect();
    let report = TradeoffReport {
        source: options.source.clone(),
        views: bench.views().to_vec(),
        references: references.iter().map(|r| r.name()).collect(),
        size: options.size,
        repeats: options.repeats.max(1),
        threshold: options.threshold,
        rows,
    };
    output::write(&options.out, &report, &images)?;
    Ok(report)
}
