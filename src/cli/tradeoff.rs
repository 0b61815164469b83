//! `stripmask tradeoff`: every speed-for-accuracy knob measured against the references.

use std::path::PathBuf;

use clap::Args;
use stripmask::db::archive::ArchiveReader;
use stripmask::db::source;
use stripmask::engine::terrain::TerrainFrame;
use stripmask::error::Result;
use stripmask::sim::flight::{Builtin, Flight};

use super::args::parse_size;

#[derive(Args, Debug)]
pub(super) struct TradeoffArgs {
    /// An archive file or http:// URL.
    pub(super) source: String,
    /// Output folder: tradeoff.md, tradeoff.csv, pareto.png and the reference pictures.
    #[arg(long, default_value = "stripmask-tradeoff")]
    pub(super) out: PathBuf,
    /// Also views along this flight: a built-in one (overview, diagonal, low) or a TOML file.
    #[arg(long)]
    pub(super) flight: Option<String>,
    /// Views taken from --flight, evenly spaced in time.
    #[arg(long, default_value_t = 3)]
    pub(super) flight_views: usize,
    /// Use only the first N built-in views (overview, oblique, low, horizon, down).
    #[arg(long)]
    pub(super) views: Option<usize>,
    /// Frame size.
    #[arg(long, value_parser = parse_size, default_value = "320x240")]
    pub(super) size: (u32, u32),
    /// Timed frames per setting and view (the median counts).
    #[arg(long, default_value_t = 5)]
    pub(super) repeats: usize,
    /// A pixel is off when a channel differs from the reference by more than this.
    #[arg(long, default_value_t = 16)]
    pub(super) threshold: u8,
    /// Turn only these knobs, comma-separated (budget, precision, perspective, filter, colour,
    /// depth, cracks, threads, texture, depth-test, lighting, fog).
    #[arg(long, value_delimiter = ',')]
    pub(super) knobs: Option<Vec<String>>,
    /// No line per setting on stderr.
    #[arg(short, long)]
    pub(super) quiet: bool,
}

pub(super) fn run(a: TradeoffArgs) -> Result<()> {
    let flight = match a.flight.as_deref() {
        None => None,
        Some(name) => {
            let reader = ArchiveReader::open(source::open(&a.source)?)?;
            let terrain = TerrainFrame::new(reader.header());
            Some(match name {
                "overview" => Flight::builtin(Builtin::Overview, &terrain),
                "diagonal" => Flight::builtin(Builtin::Diagonal, &terrain),
                "low" => Flight::builtin(Builtin::Low, &terrain),
                path => Flight::from_toml(std::path::Path::new(path))?,
            })
        }
    };
    let options = stripmask::sim::tradeoff::TradeoffOptions {
        source: a.source,
        out: a.out.clone(),
        flight,
        flight_views: a.flight_views,
        builtin_views: a.views,
        size: a.size,
        repeats: a.repeats,
        threshold: a.threshold,
        knobs: a.knobs,
        progress: !a.quiet,
    };
    let report = stripmask::sim::tradeoff::run_with(&options, tradeoff_references(a.size))?;
    let front = report.rows.iter().filter(|r| r.pareto).count();
    println!(
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
pub(super) fn tradeoff_references(
    size: (u32, u32),
) -> Vec<Box<dyn stripmask::sim::tradeoff::reference::Reference>> {
    #[cfg_attr(not(feature = "wgpu"), allow(unused_mut))]
    let mut references: Vec<Box<dyn stripmask::sim::tradeoff::reference::Reference>> =
        vec![Box::new(stripmask::sim::tradeoff::reference::CpuFloat)];
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
