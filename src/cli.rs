//! Command-line arguments and the `build`, `info`, `serve`, `fly`, `view` and `fb` commands.

use std::io::Write;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;
use stripmask::archive::{ArchiveReader, Codec, HEADER_LEN, Header};
use stripmask::builder::{BuildOptions, build};
use stripmask::cracks::CrackMode;
use stripmask::dem::{self, DemFormat, OpenOptions, RawLayout, SampleType};
use stripmask::demo::DemoOptions;
use stripmask::engine::EngineSettings;
use stripmask::error::{Error, Result};
use stripmask::flight::{Builtin, Flight};
use stripmask::fly::{FlyOptions, Length, LiveView, fly};
use stripmask::geomorph::Geomorph;
use stripmask::importance::Weights;
use stripmask::masks::LevelSet;
use stripmask::pager::memory_limit_from_available;
use stripmask::profile::{DeviceProfile, Overrides, depth_format};
use stripmask::serve::Server;
use stripmask::simclock::{Clock, CostModel};
use stripmask::source::{self, throttle::LinkProfile};
use stripmask::stream::{PredictionSettings, StreamSettings, Streaming};
use stripmask::terrain::TerrainFrame;
#[cfg(any(feature = "window", all(feature = "fbdev", target_os = "linux")))]
use stripmask::viewer::{self, ViewerOptions, ViewerSummary};
use stripmask_platform::Presenter;
use stripmask_raster::{ColorFormat, DepthFormat, Precision};

/// Adaptive streaming and CPU rendering of large terrains with strip masks.
#[derive(Parser, Debug)]
#[command(name = "stripmask", version, about)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Cut a DEM (PNG, GeoTIFF, .hgt, .asc, raw/BIL) into tiles and write a .smdb archive.
    Build(BuildArgs),
    /// Describe an archive (a file or an http:// URL).
    Info(InfoArgs),
    /// Serve one archive over HTTP with byte ranges (loopback by default).
    Serve(ServeArgs),
    /// Fly over an archive headless: stats.csv, PNG frames and a summary.
    Fly(FlyArgs),
    /// Fly over an archive in a window (WASD/arrows, Space/C, mouse drag; H HUD; Esc quits).
    View(ViewArgs),
    /// Fly over an archive on the Linux framebuffer (a scripted flight; Ctrl-C quits).
    Fb(FbArgs),
    /// Draw the flyover plots of DIR/stats.csv into DIR.
    Report(ReportArgs),
    /// The paper's PocketPC flyover over the Puget Sound model, in one command.
    Demo(DemoArgs),
    /// Measure every speed-for-accuracy knob: frame time against error, table, CSV and plot.
    Tradeoff(TradeoffArgs),
    /// Whole-tile belts against progressive tiles on the built-in flights over three links.
    StreamCompare(StreamCompareArgs),
}

/// How tiles come in, and its settings: what `fly`, `view`, `fb` and `demo` share.
#[derive(Args, Debug)]
struct StreamingArgs {
    /// belts: whole tiles, belt by belt (the paper); progressive: tile levels by importance
    /// (docs/streaming.md).
    #[arg(long, value_enum, default_value_t = StreamingArg::Belts)]
    streaming: StreamingArg,
    /// With --streaming progressive: (tile, level) requests waiting to be sent, at most.
    #[arg(long, default_value_t = 32)]
    queue: usize,
    /// With --streaming progressive: no viewpoint prediction.
    #[arg(long)]
    no_prediction: bool,
    /// With --streaming progressive: seconds ahead the viewpoint is predicted.
    #[arg(long, default_value_t = 1.0)]
    predict_seconds: f64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum StreamingArg {
    Belts,
    Progressive,
}

impl StreamingArgs {
    fn resolve(&self) -> Result<Streaming> {
        if self.streaming == StreamingArg::Belts {
            return Ok(Streaming::Belts);
        }
        if self.queue == 0 {
            return Err(Error::Usage("--queue must be at least 1".into()));
        }
        if !(self.predict_seconds > 0.0 && self.predict_seconds.is_finite()) {
            return Err(Error::Usage(format!(
                "--predict-seconds {} must be a positive number",
                self.predict_seconds
            )));
        }
        Ok(Streaming::Progressive(StreamSettings {
            queue_capacity: self.queue,
            prediction: (!self.no_prediction).then_some(PredictionSettings {
                horizon: self.predict_seconds,
                ..PredictionSettings::default()
            }),
            ..StreamSettings::default()
        }))
    }
}

#[derive(Args, Debug)]
struct StreamCompareArgs {
    /// An archive file or http:// URL.
    source: String,
    /// Output folder: stream-compare.md and stream-compare.csv.
    #[arg(long, default_value = "stripmask-stream")]
    out: PathBuf,
    /// The flights, comma-separated (default: every built-in one).
    #[arg(long, value_enum, value_delimiter = ',')]
    flights: Option<Vec<Builtin>>,
    /// Seconds of each flight (default: all of it).
    #[arg(long)]
    seconds: Option<f64>,
    /// Device profile: pocketpc, workstation or native (its link is replaced by each link).
    #[arg(long, default_value = "pocketpc")]
    profile: String,
    /// No progress bar.
    #[arg(short, long)]
    quiet: bool,
}

#[derive(Args, Debug)]
struct TradeoffArgs {
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
    /// Turn only these knobs, comma-separated (budget, precision, perspective, filter, colour,
    /// depth, cracks, threads, texture, depth-test, lighting, fog).
    #[arg(long, value_delimiter = ',')]
    knobs: Option<Vec<String>>,
    /// No line per setting on stderr.
    #[arg(short, long)]
    quiet: bool,
}

#[derive(Args, Debug)]
struct ReportArgs {
    /// A folder holding stats.csv (what `fly` or `demo` wrote).
    dir: PathBuf,
}

#[derive(Args, Debug)]
struct DemoArgs {
    /// Output folder: archive, stats.csv, frames and plots.
    #[arg(long, default_value = "stripmask-demo")]
    out: PathBuf,
    /// The elevation model (default: examples/data/puget_sound_1k_height.png).
    #[arg(long)]
    dem: Option<PathBuf>,
    /// Device profile: pocketpc, workstation or native.
    #[arg(long, default_value = "pocketpc")]
    profile: String,
    /// A TOML device profile instead of a built-in one.
    #[arg(long, conflicts_with = "profile")]
    profile_file: Option<PathBuf>,
    /// simulated (reproducible, the default) or wall (measured frame costs).
    #[arg(long, value_enum, default_value_t = ClockArg::Simulated)]
    clock: ClockArg,
    /// Stop after N frames (default: the whole flight).
    #[arg(long, conflicts_with = "seconds")]
    frames: Option<u64>,
    /// Stop after S seconds of flight time.
    #[arg(long)]
    seconds: Option<f64>,
    /// Keep one frame in K as PNG (0: none).
    #[arg(long, default_value_t = 10)]
    every: u64,
    /// Also show the flight live in a window, at the device's pace (Esc ends it early).
    #[arg(long)]
    window: bool,
    #[command(flatten)]
    streaming: StreamingArgs,
    /// No progress bar.
    #[arg(short, long)]
    quiet: bool,
}

#[derive(Args, Debug)]
struct FlyArgs {
    /// An archive file or http:// URL.
    source: String,
    /// Stop after N frames (default: the whole flight).
    #[arg(long, conflicts_with = "seconds")]
    frames: Option<u64>,
    /// Stop after S seconds of flight time.
    #[arg(long)]
    seconds: Option<f64>,
    /// Output folder for stats.csv and frames.
    #[arg(long, default_value = "stripmask-fly")]
    out: PathBuf,
    /// Keep one frame in K as PNG (0: none).
    #[arg(long, default_value_t = 10)]
    every: u64,
    /// Draw the HUD (statistics and belt minimap) into the kept frames.
    #[arg(long)]
    hud: bool,
    /// No progress bar.
    #[arg(short, long)]
    quiet: bool,
    /// Do not draw the report's plots at the end.
    #[arg(long)]
    no_plots: bool,
    #[command(flatten)]
    scene: SceneArgs,
}

/// What `view` and `fb` show: a window, or the Linux framebuffer.
#[derive(Args, Debug)]
struct ViewArgs {
    /// An archive file or http:// URL.
    source: String,
    /// Stop after N frames (default: until Esc, the window closing, or Ctrl-C).
    #[arg(long)]
    frames: Option<u64>,
    /// Start with the HUD off (H toggles it).
    #[arg(long)]
    no_hud: bool,
    #[command(flatten)]
    scene: SceneArgs,
}

#[derive(Args, Debug)]
struct FbArgs {
    #[command(flatten)]
    view: ViewArgs,
    /// The framebuffer device.
    #[arg(long, default_value = "/dev/fb0")]
    device: PathBuf,
    /// Fit a frame that differs from the screen: centre it, or scale it to fill.
    #[arg(long, value_enum, default_value_t = FitArg::Center)]
    fit: FitArg,
    /// An evdev keyboard (e.g. /dev/input/event0) to fly with the viewer's keys.
    #[arg(long)]
    input: Option<PathBuf>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum FitArg {
    Center,
    Scale,
}

/// The scene and engine settings `fly`, `view` and `fb` share.
#[derive(Args, Debug)]
struct SceneArgs {
    /// A built-in flight (overview, diagonal, low) or a TOML file of keyframes.
    #[arg(long, default_value = "diagonal")]
    flight: String,
    #[command(flatten)]
    device: DeviceArgs,
    /// Memory limit as a percentage of available memory (Linux), as in the paper.
    #[arg(long)]
    memory_percent: Option<f64>,
    /// Of the memory limit, the most tile textures may take, MB (default: no separate cap).
    #[arg(long)]
    texture_mb: Option<f64>,
    /// Use the f32 reference pipeline instead of fixed point.
    #[arg(long)]
    float: bool,
    /// Power-of-two mask levels only (geometrical mipmapping) instead of every level.
    #[arg(long)]
    pow2_masks: bool,
    /// Importance weight of distance (the height weight is 1 minus it).
    #[arg(long, default_value_t = 0.5)]
    distance_weight: f64,
    /// How cracks between tiles at different levels are hidden (docs/cracks.md).
    #[arg(long, value_enum, default_value_t = CracksArg::Stitch)]
    cracks: CracksArg,
    /// Morph the vertices coarser levels drop by distance, against popping (docs/cracks.md).
    #[arg(long, value_enum, default_value_t = GeomorphArg::Off)]
    geomorph: GeomorphArg,
    /// With --geomorph distance: vertices whose grid step spans fewer pixels than this are
    /// fully morphed, those spanning twice as many not at all.
    #[arg(long, default_value_t = Geomorph::DEFAULT_PIXELS)]
    geomorph_pixels: f64,
    #[command(flatten)]
    streaming: StreamingArgs,
}

/// A scene resolved from its arguments: the flight, the engine settings, the framebuffer, the
/// clock and the link of the device profile.
struct Scene {
    flight: Flight,
    engine: EngineSettings,
    size: (u32, u32),
    color: ColorFormat,
    depth: DepthFormat,
    target_fps: f64,
    clock: Clock,
    link: Option<LinkProfile>,
}

impl SceneArgs {
    fn resolve(&self, source_name: &str) -> Result<Scene> {
        let reader = ArchiveReader::open(source::open(source_name)?)?;
        let terrain = TerrainFrame::new(reader.header());
        drop(reader);
        let flight = match self.flight.as_str() {
            "overview" => Flight::builtin(Builtin::Overview, &terrain),
            "diagonal" => Flight::builtin(Builtin::Diagonal, &terrain),
            "low" => Flight::builtin(Builtin::Low, &terrain),
            path => Flight::from_toml(std::path::Path::new(path))?,
        };
        let device = self.device.resolve()?;
        let memory_limit_bytes = match self.memory_percent {
            Some(p) => memory_limit_from_available(p)?,
            None => device.memory_limit_bytes(),
        };
        let weights =
            Weights::new(self.distance_weight, 1.0 - self.distance_weight).ok_or_else(|| {
                Error::Usage(format!(
                    "--distance-weight {} must be within 0 ..= 1",
                    self.distance_weight
                ))
            })?;
        let texture_budget_bytes = match self.texture_mb {
            Some(mb) if mb > 0.0 && mb.is_finite() => Some((mb * 1e6) as usize),
            Some(mb) => return Err(Error::Usage(format!("--texture-mb {mb} must be positive"))),
            None => None,
        };
        let mut engine = EngineSettings {
            memory_limit_bytes,
            texture_budget_bytes,
            threads: device.threads,
            level_set: if self.pow2_masks {
                LevelSet::PowerOfTwo
            } else {
                LevelSet::All
            },
            weights,
            ..EngineSettings::default()
        };
        engine.budget.target_fps = device.target_fps;
        engine.cracks = match self.cracks {
            CracksArg::None => CrackMode::None,
            CracksArg::Shadow => CrackMode::Shadow,
            CracksArg::Skirts => CrackMode::Skirts,
            CracksArg::Stitch => CrackMode::Stitch,
        };
        engine.geomorph = match self.geomorph {
            GeomorphArg::Off => Geomorph::Off,
            GeomorphArg::Distance
                if self.geomorph_pixels > 0.0 && self.geomorph_pixels.is_finite() =>
            {
                Geomorph::Distance {
                    pixels: self.geomorph_pixels,
                }
            }
            GeomorphArg::Distance => {
                return Err(Error::Usage(format!(
                    "--geomorph-pixels {} must be a positive number",
                    self.geomorph_pixels
                )));
            }
        };
        if self.float {
            engine.render.precision = Precision::Float;
        }
        engine.streaming = self.streaming.resolve()?;
        let clock = match self.device.clock {
            ClockArg::Wall => Clock::Wall {
                slowdown: device.cpu_slowdown,
            },
            ClockArg::Simulated => Clock::Simulated {
                model: CostModel::HOST,
                slowdown: device.cpu_slowdown,
            },
        };
        Ok(Scene {
            flight,
            engine,
            size: (device.width, device.height),
            color: device.color,
            depth: device.depth,
            target_fps: device.target_fps,
            clock,
            link: (!device.link.is_unlimited())
                .then(|| device.link.to_link_profile(self.device.seed)),
        })
    }
}

/// The device a flight runs as: a profile, and values that override it.
#[derive(Args, Debug)]
struct DeviceArgs {
    /// Device profile: pocketpc, workstation or native (the handheld's screen on this CPU).
    #[arg(long, default_value = "native")]
    profile: String,
    /// A TOML device profile (see docs/pocketpc.md) instead of a built-in one.
    #[arg(long, conflicts_with = "profile")]
    profile_file: Option<PathBuf>,
    /// wall: frame costs measured; simulated: modelled, so the run is reproducible.
    #[arg(long, value_enum, default_value_t = ClockArg::Wall)]
    clock: ClockArg,
    /// Framebuffer size [profile].
    #[arg(long, value_parser = parse_size)]
    size: Option<(u32, u32)>,
    /// Colour format: rgb565 (the handheld's) or rgba8888 [profile].
    #[arg(long, value_enum)]
    color: Option<ColorArg>,
    /// Depth buffer bits: 16 or 32 [profile].
    #[arg(long, value_parser = clap::value_parser!(u8).range(16..=32))]
    depth_bits: Option<u8>,
    /// The frame rate the triangle budget aims at [profile].
    #[arg(long)]
    target_fps: Option<f64>,
    /// Memory limit on loaded tiles, MB (10^6 bytes) [profile].
    #[arg(long, conflicts_with = "memory_percent")]
    memory_mb: Option<f64>,
    /// Rasterizer threads (0: all cores) [profile].
    #[arg(long)]
    threads: Option<usize>,
    /// Frame costs are multiplied by this (the device's CPU is this many times slower) [profile].
    #[arg(long)]
    cpu_slowdown: Option<f64>,
    /// Link bandwidth, kilobits per second [profile].
    #[arg(long)]
    bandwidth_kbps: Option<f64>,
    /// Link latency per request, milliseconds [profile].
    #[arg(long)]
    latency_ms: Option<f64>,
    /// Each request's latency varies within ± this many milliseconds (seeded) [profile].
    #[arg(long)]
    jitter_ms: Option<f64>,
    /// Fraction of requests the link drops, 0..1 [profile].
    #[arg(long)]
    drop_rate: Option<f64>,
    /// Seed of the link's delays and drop decisions.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

impl DeviceArgs {
    fn resolve(&self) -> Result<DeviceProfile> {
        let depth = self
            .depth_bits
            .map(depth_format)
            .transpose()
            .map_err(Error::Usage)?;
        let overrides = Overrides {
            size: self.size,
            color: self.color.map(ColorArg::format),
            depth,
            memory_mb: self.memory_mb,
            target_fps: self.target_fps,
            threads: self.threads,
            cpu_slowdown: self.cpu_slowdown,
            bandwidth_kbps: self.bandwidth_kbps,
            latency_ms: self.latency_ms,
            jitter_ms: self.jitter_ms,
            drop_rate: self.drop_rate,
        };
        DeviceProfile::resolve(&self.profile, self.profile_file.as_deref(), &overrides)
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum ClockArg {
    Wall,
    Simulated,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum CracksArg {
    None,
    Shadow,
    Skirts,
    Stitch,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum GeomorphArg {
    Off,
    Distance,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum ColorArg {
    Rgb565,
    Rgba8888,
}

impl ColorArg {
    fn format(self) -> ColorFormat {
        match self {
            ColorArg::Rgb565 => ColorFormat::Rgb565,
            ColorArg::Rgba8888 => ColorFormat::Rgba8888,
        }
    }
}

fn parse_size(s: &str) -> std::result::Result<(u32, u32), String> {
    let (w, h) = s
        .split_once('x')
        .ok_or_else(|| format!("size {s:?} is not WxH"))?;
    let parse = |v: &str| {
        v.parse::<u32>()
            .ok()
            .filter(|&n| (1..=8192).contains(&n))
            .ok_or_else(|| format!("size {s:?}: sides are 1 ..= 8192"))
    };
    Ok((parse(w)?, parse(h)?))
}

#[derive(Args, Debug)]
struct BuildArgs {
    /// The DEM file.
    input: PathBuf,
    /// The archive to write.
    #[arg(short, long)]
    output: PathBuf,
    /// Input format (default: from the extension).
    #[arg(long, value_enum)]
    format: Option<DemFormat>,
    /// Raw/BIL: samples per row.
    #[arg(long)]
    width: Option<usize>,
    /// Raw/BIL: rows.
    #[arg(long)]
    height: Option<usize>,
    /// Raw/BIL: sample type.
    #[arg(long, value_enum)]
    sample_type: Option<SampleType>,
    /// Raw/BIL: samples are big-endian (default little-endian).
    #[arg(long)]
    big_endian: bool,
    /// Raw/BIL: bytes to skip before the first sample.
    #[arg(long, default_value_t = 0)]
    header_bytes: u64,
    /// A raw value that means "no data" (in addition to the file's own).
    #[arg(long, allow_negative_numbers = true)]
    nodata: Option<f32>,
    /// Samples per tile side, 2^n + 1.
    #[arg(long, default_value_t = 129)]
    tile_size: usize,
    /// Metres between samples (default: the file's georeferencing, else 1).
    #[arg(long)]
    spacing: Option<f64>,
    /// Metres per raw height unit.
    #[arg(long, default_value_t = 1.0)]
    vertical_scale: f64,
    /// World x, y of the north-west sample (default: the file's georeferencing, else 0, 0).
    #[arg(long, num_args = 2, value_names = ["X", "Y"], allow_negative_numbers = true)]
    origin: Option<Vec<f64>>,
    /// A colour image covering the DEM, cut into tile textures (default: ramp + hill shading).
    #[arg(long)]
    texture: Option<PathBuf>,
    /// Texels per grid cell in tile textures (1, 2, 4 or 8).
    #[arg(long, default_value_t = 1)]
    texture_factor: usize,
    /// How tile payloads are stored.
    #[arg(long, value_enum, default_value_t = Codec::Lz4)]
    codec: Codec,
    /// Metres per height quantum, shared by all tiles; a tile's relief must fit 65535 quanta.
    #[arg(long, default_value_t = stripmask::builder::DEFAULT_HEIGHT_QUANTUM)]
    height_quantum: f32,
    /// No progress bar and no summary.
    #[arg(short, long)]
    quiet: bool,
    /// Print the summary as JSON.
    #[arg(long)]
    json: bool,
}

#[derive(Args, Debug)]
struct InfoArgs {
    /// An archive file or http:// URL.
    file_or_url: String,
    /// Print JSON.
    #[arg(long)]
    json: bool,
    /// Also fetch, verify and decode every tile, and report the rate.
    #[arg(long)]
    check: bool,
}

#[derive(Args, Debug)]
struct ServeArgs {
    /// The archive to serve.
    file: PathBuf,
    /// Address to listen on (port 0 picks a free port).
    #[arg(long, default_value = "127.0.0.1:0")]
    listen: SocketAddr,
    /// Simulated bandwidth per connection, kilobits per second.
    #[arg(long)]
    bandwidth_kbps: Option<f64>,
    /// Simulated latency before each answer, milliseconds.
    #[arg(long, default_value_t = 0)]
    latency_ms: u64,
    /// Each answer's latency varies within ± this many milliseconds.
    #[arg(long, default_value_t = 0)]
    jitter_ms: u64,
    /// Fraction of requests answered 503, 0..1.
    #[arg(long, default_value_t = 0.0)]
    drop_rate: f64,
    /// Seed of the latency and drop decisions.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

/// Runs one command.
pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Build(a) => run_build(a),
        Command::Info(a) => run_info(a),
        Command::Serve(a) => run_serve(a),
        Command::Fly(a) => run_fly(a),
        Command::View(a) => run_view(a),
        Command::Fb(a) => run_fb(a),
        Command::Report(a) => run_report(a),
        Command::Demo(a) => run_demo(a),
        Command::Tradeoff(a) => run_tradeoff(a),
        Command::StreamCompare(a) => run_stream_compare(a),
    }
}

#[cfg(any(feature = "window", all(feature = "fbdev", target_os = "linux")))]
fn viewer_options(a: &ViewArgs) -> Result<ViewerOptions> {
    let scene = a.scene.resolve(&a.source)?;
    let mut engine = scene.engine;
    // A fetch thread on the wall clock; on the simulated clock (`--clock simulated`) fetches that
    // complete at reproducible frames, so that `--frames N` shows what `fly` draws at frame N - 1.
    engine.pager_mode = scene.clock.pager_mode(4);
    Ok(ViewerOptions {
        source: a.source.clone(),
        size: scene.size,
        color: scene.color,
        depth: scene.depth,
        engine,
        hud: !a.no_hud,
        flight: scene.flight,
        frames: a.frames,
        clock: scene.clock,
    })
}

#[cfg(any(feature = "window", all(feature = "fbdev", target_os = "linux")))]
fn report_view(s: ViewerSummary) {
    println!(
        "{} frames in {:.1} s ({:.1} fps)",
        s.frames,
        s.seconds,
        s.frames as f64 / s.seconds.max(1e-9)
    );
}

#[cfg(feature = "window")]
fn run_view(a: ViewArgs) -> Result<()> {
    let options = viewer_options(&a)?;
    let (w, h) = options.size;
    let mut window =
        stripmask_platform::WindowPresenter::open(&format!("stripmask: {}", a.source), w, h)
            .map_err(|e| Error::Usage(e.to_string()))?;
    report_view(viewer::run(&mut window, &options)?);
    Ok(())
}

#[cfg(not(feature = "window"))]
fn run_view(_: ViewArgs) -> Result<()> {
    Err(Error::Usage(
        "this stripmask was built without the `window` feature".into(),
    ))
}

#[cfg(all(feature = "fbdev", target_os = "linux"))]
fn run_fb(a: FbArgs) -> Result<()> {
    let options = viewer_options(&a.view)?;
    let fit = match a.fit {
        FitArg::Center => stripmask_platform::Fit::Center,
        FitArg::Scale => stripmask_platform::Fit::Scale,
    };
    let mut screen = stripmask_platform::FbPresenter::open(&a.device, fit)
        .map_err(|e| Error::Usage(e.to_string()))?;
    if let Some(path) = &a.input {
        let keyboard =
            stripmask_platform::EvdevInput::open(path).map_err(|e| Error::Usage(e.to_string()))?;
        screen = screen.with_input(keyboard);
    }
    report_view(viewer::run(&mut screen, &options)?);
    Ok(())
}

#[cfg(not(all(feature = "fbdev", target_os = "linux")))]
fn run_fb(_: FbArgs) -> Result<()> {
    Err(Error::Usage(
        "this stripmask was built without the `fbdev` feature (Linux only)".into(),
    ))
}

fn run_fly(a: FlyArgs) -> Result<()> {
    let scene = a.scene.resolve(&a.source)?;
    let options = FlyOptions {
        source: a.source.clone(),
        flight: scene.flight,
        length: match (a.frames, a.seconds) {
            (Some(n), _) => Some(Length::Frames(n)),
            (None, Some(s)) => Some(Length::Seconds(s)),
            (None, None) => None,
        },
        size: scene.size,
        color: scene.color,
        depth: scene.depth,
        engine: scene.engine,
        out: a.out.clone(),
        every: a.every,
        hud: a.hud,
        progress: !a.quiet,
        clock: scene.clock,
        link: scene.link,
        plots: !a.no_plots,
    };
    let s = fly(&options)?;
    println!(
        "{} frames over {:.1} s of flight: median {:.1} fps (target {}), {:.0} triangles per frame, \
         peak memory {:.1} of {:.1} MB, {:.2} MB downloaded, first frame at {} -> {}",
        s.frames,
        s.seconds,
        s.median_fps,
        scene.target_fps,
        s.mean_triangles,
        s.peak_memory_bytes as f64 / 1e6,
        s.memory_limit_bytes as f64 / 1e6,
        s.downloaded_bytes as f64 / 1e6,
        s.first_frame_s
            .map_or("never".into(), |t| format!("{t:.2} s")),
        a.out.join("stats.csv").display()
    );
    Ok(())
}

fn run_report(a: ReportArgs) -> Result<()> {
    for path in stripmask::report::draw(&a.dir)? {
        println!("{}", path.display());
    }
    Ok(())
}

fn run_demo(a: DemoArgs) -> Result<()> {
    let options = DemoOptions {
        out: a.out,
        dem: a.dem,
        profile: DeviceProfile::resolve(
            &a.profile,
            a.profile_file.as_deref(),
            &Overrides::default(),
        )?,
        simulated: a.clock == ClockArg::Simulated,
        length: match (a.frames, a.seconds) {
            (Some(n), _) => Some(Length::Frames(n)),
            (None, Some(s)) => Some(Length::Seconds(s)),
            (None, None) => None,
        },
        every: a.every,
        progress: !a.quiet,
        streaming: a.streaming.resolve()?,
    };
    if !a.window {
        println!("{}", stripmask::demo::run(&options)?);
        return Ok(());
    }
    let p = &options.profile;
    // A handheld's screen is small on a desktop: scale the window up to about 960 pixels wide.
    let scale = (960 / p.width).max(1);
    match open_window("stripmask demo", p.width * scale, p.height * scale) {
        Ok(mut window) => {
            let live = LiveView {
                presenter: window.as_mut(),
                real_time: true,
            };
            println!("{}", stripmask::demo::run_live(&options, Some(live))?);
            Ok(())
        }
        Err(problem) => {
            eprintln!("stripmask demo: --window: {problem}; running headless");
            println!("{}", stripmask::demo::run(&options)?);
            Err(Error::Usage(format!(
                "--window: {problem} (the demo ran headless and wrote its outputs)"
            )))
        }
    }
}

/// A window for live frames, or why there is none.
#[cfg(feature = "window")]
fn open_window(
    title: &str,
    width: u32,
    height: u32,
) -> std::result::Result<Box<dyn Presenter>, String> {
    stripmask_platform::WindowPresenter::open(title, width, height)
        .map(|w| Box::new(w) as Box<dyn Presenter>)
        .map_err(|e| e.to_string())
}

#[cfg(not(feature = "window"))]
fn open_window(_: &str, _: u32, _: u32) -> std::result::Result<Box<dyn Presenter>, String> {
    Err("this stripmask was built without the `window` feature".into())
}

fn run_stream_compare(a: StreamCompareArgs) -> Result<()> {
    use stripmask::stream::compare::{self, CompareOptions, LINKS};
    if let Some(s) = a.seconds.filter(|s| !(*s > 0.0 && s.is_finite())) {
        return Err(Error::Usage(format!(
            "--seconds {s} must be a positive number"
        )));
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

fn run_tradeoff(a: TradeoffArgs) -> Result<()> {
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
    let options = stripmask::tradeoff::TradeoffOptions {
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
    let report = stripmask::tradeoff::run_with(&options, tradeoff_references(a.size))?;
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
fn tradeoff_references(
    size: (u32, u32),
) -> Vec<Box<dyn stripmask::tradeoff::reference::Reference>> {
    #[cfg_attr(not(feature = "wgpu"), allow(unused_mut))]
    let mut references: Vec<Box<dyn stripmask::tradeoff::reference::Reference>> =
        vec![Box::new(stripmask::tradeoff::reference::CpuFloat)];
    #[cfg(feature = "wgpu")]
    match stripmask::tradeoff::reference::Gpu::new(size) {
        Ok(gpu) => {
            eprintln!("wgpu reference on {}", gpu.adapter());
            references.push(Box::new(gpu));
        }
        Err(e) => eprintln!("wgpu reference skipped: {e}"),
    }
    references
}

fn run_build(a: BuildArgs) -> Result<()> {
    let raw = match (a.width, a.height, a.sample_type) {
        (Some(width), Some(height), Some(sample_type)) => Some(RawLayout {
            width,
            height,
            sample_type,
            big_endian: a.big_endian,
            header_bytes: a.header_bytes,
        }),
        (None, None, None) => None,
        _ => {
            return Err(Error::Usage(
                "--width, --height and --sample-type go together".into(),
            ));
        }
    };
    let reader = dem::open(
        &a.input,
        &OpenOptions {
            format: a.format,
            raw,
            nodata: a.nodata,
        },
    )?;
    let options = BuildOptions {
        tile_size: a.tile_size,
        spacing: a.spacing,
        vertical_scale: a.vertical_scale,
        origin: a.origin.map(|o| (o[0], o[1])),
        texture_factor: a.texture_factor,
        texture_image: a.texture,
        codec: a.codec,
        height_quantum: a.height_quantum,
    };
    let bar = if a.quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(0).with_style(
            ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {pos}/{len} tiles {eta}")
                .expect("valid template")
                .progress_chars("=> "),
        )
    };
    let report = build(reader, &a.output, &options, &|done, total| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    })?;
    bar.finish_and_clear();
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&report).expect("serialisable")
        );
    } else if !a.quiet {
        let h = &report.header;
        println!(
            "{}: {} x {} tiles of {} samples, {} bytes ({:.1} KiB per tile stored, {:.1} KiB raw) in {:.2} s",
            a.output.display(),
            h.tiles_x,
            h.tiles_y,
            h.tile_size,
            report.archive_bytes,
            report.stored_payload_bytes as f64 / h.tile_count() as f64 / 1024.0,
            report.raw_payload_bytes as f64 / h.tile_count() as f64 / 1024.0,
            report.seconds
        );
    }
    Ok(())
}

#[derive(Serialize)]
struct InfoReport {
    name: String,
    version: u32,
    header: Header,
    tile_count: usize,
    file_bytes: u64,
    main_bytes: u64,
    raw_tile_bytes: usize,
    stored_tile_bytes_min: u64,
    stored_tile_bytes_mean: f64,
    stored_tile_bytes_max: u64,
    stored_tile_bytes: Vec<u64>,
    raw_level_bytes: Vec<usize>,
    stored_level_bytes_mean: Vec<f64>,
    check: Option<CheckReport>,
}

#[derive(Serialize)]
struct CheckReport {
    tiles: usize,
    bytes: u64,
    seconds: f64,
    tiles_per_second: f64,
    mebibytes_per_second: f64,
}

fn run_info(a: InfoArgs) -> Result<()> {
    let source = source::open(&a.file_or_url)?;
    let file_bytes = source.size()?;
    let reader = ArchiveReader::open(source)?;
    let h = reader.header().clone();
    let lengths: Vec<u64> = reader.index().iter().map(|e| e.stored_len()).collect();
    let stored_level_bytes_mean = (0..h.levels())
        .map(|g| {
            let sum: u64 = reader.index().iter().map(|e| e.range(g..g + 1).1).sum();
            sum as f64 / lengths.len().max(1) as f64
        })
        .collect();
    let check = if a.check {
        let started = Instant::now();
        let mut bytes = 0;
        for ty in 0..h.tiles_y as usize {
            for tx in 0..h.tiles_x as usize {
                reader.tile(tx, ty)?;
                bytes += lengths[ty * h.tiles_x as usize + tx];
            }
        }
        let seconds = started.elapsed().as_secs_f64().max(1e-9);
        Some(CheckReport {
            tiles: h.tile_count(),
            bytes,
            seconds,
            tiles_per_second: h.tile_count() as f64 / seconds,
            mebibytes_per_second: bytes as f64 / seconds / (1024.0 * 1024.0),
        })
    } else {
        None
    };
    let report = InfoReport {
        name: a.file_or_url.clone(),
        version: stripmask::archive::VERSION,
        tile_count: h.tile_count(),
        file_bytes,
        main_bytes: (HEADER_LEN + h.index_len()) as u64,
        raw_tile_bytes: h.payload_size(),
        stored_tile_bytes_min: lengths.iter().copied().min().unwrap_or(0),
        stored_tile_bytes_mean: lengths.iter().map(|&l| l as f64).sum::<f64>()
            / lengths.len().max(1) as f64,
        stored_tile_bytes_max: lengths.iter().copied().max().unwrap_or(0),
        stored_tile_bytes: lengths,
        raw_level_bytes: (0..h.levels()).map(|g| h.level_payload_size(g)).collect(),
        stored_level_bytes_mean,
        header: h,
        check,
    };
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&report).expect("serialisable")
        );
        return Ok(());
    }
    let h = &report.header;
    let mut out = String::new();
    let mut line = |s: String| {
        out.push_str(&s);
        out.push('\n');
    };
    line(format!(
        "archive     {} (format version {})",
        report.name, report.version
    ));
    line(format!(
        "grid        {} x {} tiles of {} x {} samples, from a {} x {} DEM",
        h.tiles_x, h.tiles_y, h.tile_size, h.tile_size, h.source_width, h.source_height
    ));
    line(format!(
        "spacing     {} m, vertical scale {} m per unit, origin ({}, {})",
        h.spacing, h.vertical_scale, h.origin_x, h.origin_y
    ));
    line(format!(
        "heights     {} .. {} m in quanta of {} m",
        h.min_height, h.max_height, h.height_quantum
    ));
    line(format!(
        "texture     {0} x {0} RGB565 per tile with mipmaps; payload codec {1:?}",
        h.texture_size, h.codec
    ));
    line(format!(
        "bytes       {} in all; header + index {}; per tile {} raw, stored {} / {:.0} / {} (min / mean / max)",
        report.file_bytes,
        report.main_bytes,
        report.raw_tile_bytes,
        report.stored_tile_bytes_min,
        report.stored_tile_bytes_mean,
        report.stored_tile_bytes_max
    ));
    let levels: Vec<String> = report
        .raw_level_bytes
        .iter()
        .zip(&report.stored_level_bytes_mean)
        .map(|(raw, stored)| format!("{raw} -> {stored:.0}"))
        .collect();
    line(format!(
        "levels      {} progressive, bytes per tile raw -> stored (mean), coarse first: {}",
        levels.len(),
        levels.join(", ")
    ));
    if let Some(c) = &report.check {
        line(format!(
            "check       {} tiles verified and decoded in {:.3} s: {:.1} tiles/s, {:.2} MiB/s",
            c.tiles, c.seconds, c.tiles_per_second, c.mebibytes_per_second
        ));
    }
    print!("{out}");
    Ok(())
}

fn run_serve(a: ServeArgs) -> Result<()> {
    if !(0.0..=1.0).contains(&a.drop_rate) {
        return Err(Error::Usage(format!(
            "--drop-rate {} is not between 0 and 1",
            a.drop_rate
        )));
    }
    if let Some(b) = a.bandwidth_kbps.filter(|b| !(b.is_finite() && *b > 0.0)) {
        return Err(Error::Usage(format!(
            "--bandwidth-kbps {b} must be positive"
        )));
    }
    let profile = LinkProfile {
        bandwidth_kbps: a.bandwidth_kbps,
        latency: Duration::from_millis(a.latency_ms),
        jitter: Duration::from_millis(a.jitter_ms),
        drop_rate: a.drop_rate,
        seed: a.seed,
    };
    let server = Server::start(&a.file, a.listen, profile)?;
    println!("{}", server.url());
    let _ = std::io::stdout().flush();
    server.wait();
    Ok(())
}
