//! `stripmask demo`: the paper's PocketPC experiment in one command.
//!
//! Builds an archive from the Puget Sound 1k elevation model (160 m between samples, 0.1 m per
//! unit; public domain, carried inside the program so the demo needs nothing but the binary)
//! into the output folder — or reuses the one there when it is
//! intact and was built with the same settings — then flies the paper's corner-to-corner
//! diagonal as the PocketPC profile (320x240 RGB565, 20 MB, 7 fps, 1 Mbit/s link) on the
//! simulated clock, headless, and writes frames, `stats.csv` and the report's plots beside it.
//! [`run_live`] also shows the flight in a window as it runs, at the device's pace.

use std::fmt;
use std::path::{Path, PathBuf};

use crate::db::archive::ArchiveReader;
use crate::db::builder::{BuildOptions, build_opening};
use crate::db::dem::{self, DemReader, NodataFill, OpenOptions};
use crate::db::source::{self, file::FileSource};
use crate::engine::EngineSettings;
use crate::engine::paging::stream::Streaming;
use crate::engine::terrain::TerrainFrame;
use crate::error::{Error, Result};
use crate::sim::clock::{Clock, CostModel};
use crate::sim::device::DeviceProfile;
use crate::sim::flight::{Builtin, Flight};
use crate::sim::fly::{FlyOptions, FlySummary, Length, LiveView, fly_live};

/// The demo's elevation model, as carried in the program: a 16-bit grayscale PNG of
/// 1025 x 1025 samples (`examples/data/puget_sound_1k_height.png`).
pub const DEM_PNG: &[u8] = include_bytes!("../../examples/data/puget_sound_1k_height.png");
/// The name the carried model goes by in messages.
const DEM_NAME: &str = "puget_sound_1k_height.png (built in)";
/// The archive's name inside the output folder.
pub const ARCHIVE: &str = "puget.smdb";
/// Metres between samples of the 1k model (16 x the 10 m of the full one).
pub const SPACING: f64 = 160.0;
/// Metres per raw height unit.
pub const VERTICAL_SCALE: f64 = 0.1;
/// Samples per tile side: 16 x 16 tiles, so that belts matter under 20 MB.
pub const TILE_SIZE: usize = 65;

/// What the demo runs.
#[derive(Clone, Debug)]
pub struct DemoOptions {
    /// Output folder.
    pub out: PathBuf,
    /// The elevation model (default: [`DEM_PNG`], carried in the program).
    pub dem: Option<PathBuf>,
    /// The device.
    pub profile: DeviceProfile,
    /// The simulated clock (reproducible) or the wall clock; the profile's CPU slowdown
    /// replaces the clock's own.
    pub clock: Clock,
    /// When to stop (default: the whole flight).
    pub length: Option<Length>,
    /// Keep one frame in `every`.
    pub every: u64,
    /// Show progress.
    pub progress: bool,
    /// Whole-tile belts (the paper, the default) or progressive tiles.
    pub streaming: Streaming,
}

impl Default for DemoOptions {
    fn default() -> Self {
        DemoOptions {
            out: PathBuf::from("stripmask-demo"),
            dem: None,
            profile: DeviceProfile::pocketpc(),
            clock: Clock::Simulated {
                model: CostModel::HOST,
                slowdown: 1.0,
            },
            length: None,
            every: 10,
            progress: true,
            streaming: Streaming::Belts,
        }
    }
}

/// What the demo did.
#[derive(Clone, Debug)]
pub struct DemoSummary {
    /// The archive flown over.
    pub archive: PathBuf,
    /// The elevation model it was built from now, or `None` when an intact one was reused.
    pub built_from: Option<String>,
    /// The device.
    pub profile: DeviceProfile,
    /// The flight's summary.
    pub fly: FlySummary,
    /// Fraction of frames after the first second whose frame rate is within 10% of the target.
    pub held: f64,
    /// The output folder.
    pub out: PathBuf,
}

impl fmt::Display for DemoSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = &self.fly;
        let p = &self.profile;
        writeln!(
            f,
            "archive      {} ({})",
            self.archive.display(),
            match &self.built_from {
                Some(model) => format!("built from {model}"),
                None => "reused".into(),
            }
        )?;
        writeln!(
            f,
            "device       {}: {}x{}, {} MB, {} thread(s), CPU {}x slower, link {}",
            p.name,
            p.width,
            p.height,
            p.memory_mb,
            p.threads,
            p.cpu_slowdown,
            link_text(p)
        )?;
        writeln!(
            f,
            "frame rate   median {:.1} fps, target {}; {:.0}% of frames after the first second within 10%",
            s.median_fps,
            p.target_fps,
            100.0 * self.held
        )?;
        writeln!(
            f,
            "triangles    {:.0} per frame on average over {} frames ({:.1} s of flight)",
            s.mean_triangles, s.frames, s.seconds
        )?;
        writeln!(
            f,
            "memory       peak {:.2} MB of {:.2} MB; {:.2} MB downloaded",
            s.peak_memory_bytes as f64 / 1e6,
            s.memory_limit_bytes as f64 / 1e6,
            s.downloaded_bytes as f64 / 1e6
        )?;
        writeln!(f, "holes        {}", s.holes)?;
        write!(
            f,
            "written      {}: stats.csv, frames/, fps.png, triangles.png, downloads.png, tiles.png, memory.png",
            self.out.display()
        )
    }
}

fn link_text(p: &DeviceProfile) -> String {
    match p.link.bandwidth_kbps {
        Some(kbps) => format!(
            "{kbps} kbit/s, {} ms latency{}, {}% dropped",
            p.link.latency.as_nanos() as f64 / 1e6,
            if !p.link.jitter.is_zero() {
                format!(" ± {} ms", p.link.jitter.as_nanos() as f64 / 1e6)
            } else {
                String::new()
            },
            100.0 * p.link.drop_rate
        ),
        None => "unlimited".into(),
    }
}

/// Runs the demo.
pub fn run(o: &DemoOptions) -> Result<DemoSummary> {
    run_live(o, None)
}

/// Runs the demo, showing the flight in `live` as well when given.
pub fn run_live(o: &DemoOptions, live: Option<LiveView<'_>>) -> Result<DemoSummary> {
    let out_name = o.out.display().to_string();
    std::fs::create_dir_all(&o.out).map_err(|e| Error::io(&out_name, e))?;
    let archive = o.out.join(ARCHIVE);
    let built_from = if intact(&archive) {
        None
    } else {
        let open = || match &o.dem {
            Some(path) => dem::open(path, &OpenOptions::default()),
            None => dem::open_png_bytes(DEM_NAME, DEM_PNG),
        };
        let model = open()?.info().name.clone();
        build_archive(open, &archive)?;
        Some(model)
    };
    let archive_name = archive.display().to_string();
    let reader = ArchiveReader::open(source::open(&archive_name)?)?;
    let terrain = TerrainFrame::new(reader.header());
    drop(reader);
    let p = &o.profile;
    let mut engine = EngineSettings {
        memory_limit_bytes: p.memory_limit_bytes(),
        threads: p.threads,
        streaming: o.streaming,
        max_error: p.max_error()?,
        allocation: p.allocation,
        ..EngineSettings::default()
    };
    let clock = o.clock.with_slowdown(p.cpu_slowdown);
    engine.budget = p.budget(clock);
    let fly_options = FlyOptions {
        source: archive_name,
        flight: Flight::builtin(Builtin::Diagonal, &terrain),
        length: o.length,
        size: (p.width, p.height),
        color: p.color,
        depth: p.depth,
        engine,
        out: o.out.clone(),
        every: o.every,
        hud: true,
        progress: o.progress,
        clock,
        link: (!p.link.is_unlimited()).then_some(p.link),
        plots: true,
        http: crate::db::source::http::HttpOptions::default(),
    };
    let summary = fly_live(&fly_options, live)?;
    Ok(DemoSummary {
        archive,
        built_from,
        profile: p.clone(),
        held: held_fraction(&o.out, p.target_fps)?,
        fly: summary,
        out: o.out.clone(),
    })
}

/// Builds the demo's archive from `dem` into `archive` (through a temporary file, so that an
/// interrupted build never leaves a half-written archive behind).
fn build_archive(
    open: impl FnMut() -> Result<NodataFill<Box<dyn DemReader>>>,
    archive: &Path,
) -> Result<()> {
    let options = BuildOptions {
        tile_size: TILE_SIZE,
        spacing: Some(SPACING),
        vertical_scale: VERTICAL_SCALE,
        ..BuildOptions::default()
    };
    let partial = archive.with_extension("smdb.partial");
    build_opening(open, &partial, &options, &|_, _| {})?;
    std::fs::rename(&partial, archive).map_err(|e| Error::io(archive.display().to_string(), e))
}

/// Whether `archive` opens, was built with the demo's settings, and every tile passes its
/// checksum and decodes.
fn intact(archive: &Path) -> bool {
    let Ok(source) = FileSource::open(archive) else {
        return false;
    };
    let Ok(reader) = ArchiveReader::open_with_attempts(source, 1) else {
        return false;
    };
    let h = reader.header();
    let same = h.tile_size as usize == TILE_SIZE
        && h.spacing == SPACING
        && h.vertical_scale == VERTICAL_SCALE
        && (h.source_width, h.source_height) == (1025, 1025);
    same && reader.check().is_ok()
}

/// Fraction of the frames after the first second of flight within 10% of `target` fps.
fn held_fraction(out: &Path, target: f64) -> Result<f64> {
    let table = crate::sim::report::StatsTable::read(&out.join("stats.csv"))?;
    let time = table.column("time_s")?;
    let fps = table.column("fps")?;
    let settled: Vec<f64> = time
        .iter()
        .zip(&fps)
        .filter(|(t, _)| **t >= 1.0)
        .map(|(_, f)| *f)
        .collect();
    let within = settled
        .iter()
        .filter(|f| (**f / target - 1.0).abs() <= 0.1)
        .count();
    Ok(within as f64 / settled.len().max(1) as f64)
}
