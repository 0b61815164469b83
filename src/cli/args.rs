//! Argument groups several commands share (the scene, the device, the streaming), and how each
//! resolves into the library's settings.

use std::path::PathBuf;

use clap::Args;
use stripmask::db::archive::ArchiveReader;
use stripmask::db::source::{self, throttle::LinkProfile};
use stripmask::engine::EngineSettings;
use stripmask::engine::cracks::CrackMode;
use stripmask::engine::geomorph::Geomorph;
use stripmask::engine::importance::Weights;
use stripmask::engine::masks::LevelSet;
use stripmask::engine::paging::memory_limit_from_available;
use stripmask::engine::paging::stream::{PredictionSettings, StreamSettings, Streaming};
use stripmask::engine::terrain::TerrainFrame;
use stripmask::error::{Error, Result};
use stripmask::sim::clock::{Clock, CostModel};
use stripmask::sim::device::{DeviceProfile, Overrides, depth_format};
use stripmask::sim::flight::{Builtin, Flight};
use stripmask_raster::{ColorFormat, DepthFormat, Precision};

/// How tiles come in, and its settings: what `fly`, `view`, `fb` and `demo` share.
#[derive(Args, Debug)]
pub(super) struct StreamingArgs {
    /// belts: whole tiles, belt by belt (the paper); progressive: tile levels by importance
    /// (docs/streaming.md).
    #[arg(long, value_enum, default_value_t = StreamingArg::Belts)]
    pub(super) streaming: StreamingArg,
    /// With --streaming progressive: (tile, level) requests waiting to be sent, at most.
    #[arg(long, default_value_t = 32)]
    pub(super) queue: usize,
    /// With --streaming progressive: no viewpoint prediction.
    #[arg(long)]
    pub(super) no_prediction: bool,
    /// With --streaming progressive: seconds ahead the viewpoint is predicted.
    #[arg(long, default_value_t = 1.0)]
    pub(super) predict_seconds: f64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub(super) enum StreamingArg {
    Belts,
    Progressive,
}

impl StreamingArgs {
    pub(super) fn resolve(&self) -> Result<Streaming> {
        if self.streaming == StreamingArg::Belts {
            return Ok(Streaming::Belts);
        }
        if self.queue == 0 {
            return Err(Error::setting("--queue", 0, "at least 1"));
        }
        positive("--predict-seconds", self.predict_seconds)?;
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

/// The scene and engine settings `fly`, `view` and `fb` share.
#[derive(Args, Debug)]
pub(super) struct SceneArgs {
    /// A built-in flight (overview, diagonal, low) or a TOML file of keyframes.
    #[arg(long, default_value = "diagonal")]
    pub(super) flight: String,
    #[command(flatten)]
    pub(super) device: DeviceArgs,
    /// Memory limit as a percentage of available memory (Linux), as in the paper.
    #[arg(long)]
    pub(super) memory_percent: Option<f64>,
    /// Of the memory limit, the most tile textures may take, MB (default: no separate cap).
    #[arg(long)]
    pub(super) texture_mb: Option<f64>,
    /// Use the f32 reference pipeline instead of fixed point.
    #[arg(long)]
    pub(super) float: bool,
    /// Power-of-two mask levels only (geometrical mipmapping) instead of every level.
    #[arg(long)]
    pow2_masks: bool,
    /// Importance weight of distance (the height weight is 1 minus it).
    #[arg(long, default_value_t = 0.5)]
    pub(super) distance_weight: f64,
    /// How cracks between tiles at different levels are hidden (docs/cracks.md).
    #[arg(long, value_enum, default_value_t = CracksArg::Stitch)]
    pub(super) cracks: CracksArg,
    /// Morph the vertices coarser levels drop by distance, against popping (docs/cracks.md).
    #[arg(long, value_enum, default_value_t = GeomorphArg::Off)]
    pub(super) geomorph: GeomorphArg,
    /// With --geomorph distance: vertices whose grid step spans fewer pixels than this are
    /// fully morphed, those spanning twice as many not at all.
    #[arg(long, default_value_t = Geomorph::DEFAULT_PIXELS)]
    pub(super) geomorph_pixels: f64,
    #[command(flatten)]
    pub(super) streaming: StreamingArgs,
}

/// A scene resolved from its arguments: the flight, the engine settings, the framebuffer, the
/// clock and the link of the device profile.
pub(super) struct Scene {
    pub(super) flight: Flight,
    pub(super) engine: EngineSettings,
    pub(super) size: (u32, u32),
    pub(super) color: ColorFormat,
    pub(super) depth: DepthFormat,
    pub(super) target_fps: f64,
    pub(super) clock: Clock,
    pub(super) link: Option<LinkProfile>,
}

impl SceneArgs {
    pub(super) fn resolve(&self, source_name: &str) -> Result<Scene> {
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
                Error::setting(
                    "--distance-weight",
                    self.distance_weight,
                    "a weight within 0 ..= 1",
                )
            })?;
        let texture_budget_bytes = match self.texture_mb {
            Some(mb) => Some((positive("--texture-mb", mb)? * 1e6) as usize),
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
            GeomorphArg::Distance => Geomorph::Distance {
                pixels: positive("--geomorph-pixels", self.geomorph_pixels)?,
            },
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
pub(super) struct DeviceArgs {
    /// Device profile: pocketpc, workstation or native (the handheld's screen on this CPU).
    #[arg(long, default_value = "native")]
    pub(super) profile: String,
    /// A TOML device profile (see docs/pocketpc.md) instead of a built-in one.
    #[arg(long, conflicts_with = "profile")]
    pub(super) profile_file: Option<PathBuf>,
    /// wall: frame costs measured; simulated: modelled, so the run is reproducible.
    #[arg(long, value_enum, default_value_t = ClockArg::Wall)]
    pub(super) clock: ClockArg,
    /// Framebuffer size [profile].
    #[arg(long, value_parser = parse_size)]
    pub(super) size: Option<(u32, u32)>,
    /// Colour format: rgb565 (the handheld's) or rgba8888 [profile].
    #[arg(long, value_enum)]
    pub(super) color: Option<ColorArg>,
    /// Depth buffer bits: 16 or 32 [profile].
    #[arg(long, value_parser = clap::value_parser!(u8).range(16..=32))]
    pub(super) depth_bits: Option<u8>,
    /// The frame rate the triangle budget aims at [profile].
    #[arg(long)]
    pub(super) target_fps: Option<f64>,
    /// Memory limit on loaded tiles, MB (10^6 bytes) [profile].
    #[arg(long, conflicts_with = "memory_percent")]
    pub(super) memory_mb: Option<f64>,
    /// Rasterizer threads (0: all cores) [profile].
    #[arg(long)]
    pub(super) threads: Option<usize>,
    /// Frame costs are multiplied by this (the device's CPU is this many times slower) [profile].
    #[arg(long)]
    pub(super) cpu_slowdown: Option<f64>,
    /// Link bandwidth, kilobits per second [profile].
    #[arg(long)]
    pub(super) bandwidth_kbps: Option<f64>,
    /// Link latency per request, milliseconds [profile].
    #[arg(long)]
    pub(super) latency_ms: Option<f64>,
    /// Each request's latency varies within ± this many milliseconds (seeded) [profile].
    #[arg(long)]
    pub(super) jitter_ms: Option<f64>,
    /// Fraction of requests the link drops, 0..1 [profile].
    #[arg(long)]
    pub(super) drop_rate: Option<f64>,
    /// Seed of the link's delays and drop decisions.
    #[arg(long, default_value_t = 1)]
    pub(super) seed: u64,
}

impl DeviceArgs {
    pub(super) fn resolve(&self) -> Result<DeviceProfile> {
        let depth = self.depth_bits.map(depth_format).transpose()?;
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
pub(super) enum ClockArg {
    Wall,
    Simulated,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub(super) enum CracksArg {
    None,
    Shadow,
    Skirts,
    Stitch,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub(super) enum GeomorphArg {
    Off,
    Distance,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub(super) enum ColorArg {
    Rgb565,
    Rgba8888,
}

impl ColorArg {
    pub(super) fn format(self) -> ColorFormat {
        match self {
            ColorArg::Rgb565 => ColorFormat::Rgb565,
            ColorArg::Rgba8888 => ColorFormat::Rgba8888,
        }
    }
}

/// `value` of `flag` when it is a positive number; an [`Error::InvalidSetting`] otherwise.
pub(super) fn positive(flag: &'static str, value: f64) -> Result<f64> {
    if value > 0.0 && value.is_finite() {
        Ok(value)
    } else {
        Err(Error::setting(flag, value, "a positive number"))
    }
}

pub(super) fn parse_size(s: &str) -> std::result::Result<(u32, u32), String> {
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
