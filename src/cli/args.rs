//! Argument groups several commands share (the scene, the streaming), how each resolves into the
//! library's settings, and the value parsers of library settings.
//!
//! Settings chosen by name parse straight into the library's types ([`named`]), and defaults come
//! from the library's own (`EngineSettings::default()` and the like), so the command holds no
//! second copy of either.

use clap::Args;
use clap::builder::{PossibleValuesParser, TypedValueParser};
use stripmask::Named;
use stripmask::db::archive::ArchiveReader;
use stripmask::db::source::http::HttpOptions;
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
use stripmask::sim::clock::Clock;
use stripmask::sim::device::DeviceProfile;
use stripmask::sim::flight::{Builtin, Flight};
use stripmask::sim::fly::Length;
use stripmask_raster::{ColorFormat, DepthFormat, Precision};

use super::device::DeviceArgs;

/// How tiles come in, and its settings: what `fly`, `view`, `fb` and `demo` share.
#[derive(Args, Debug)]
pub(super) struct StreamingArgs {
    /// belts: whole tiles, belt by belt (the paper); progressive: tile levels as the view needs
    /// them, the worst-looking tile first (docs/streaming.md).
    #[arg(long, value_parser = named::<Streaming>(), default_value = Streaming::default().name())]
    streaming: Streaming,
    /// With --streaming progressive: (tile, level) requests waiting to be sent, at most.
    #[arg(long, default_value_t = StreamSettings::default().queue_capacity)]
    queue: usize,
    /// With --streaming progressive: fill the square of belts around the viewer with the
    /// tiles' coarsest level while the link would idle, up to this share of the memory (0: no
    /// fill; the archive's top already covers every view).
    #[arg(long, default_value_t = StreamSettings::default().square_share)]
    belt_fill: f64,
    /// With --streaming progressive: prefetch for the viewpoint predicted ahead (fuller frames
    /// sooner, some bytes no frame draws).
    #[arg(long)]
    predict: bool,
    /// With --predict: seconds ahead the viewpoint is predicted.
    #[arg(
        long,
        default_value_t = PredictionSettings::default().horizon,
        allow_negative_numbers = true,
        requires = "predict"
    )]
    predict_seconds: f64,
}

impl StreamingArgs {
    /// The streaming asked for, progressive with the queue and prediction given.
    pub(super) fn resolve(&self) -> Result<Streaming> {
        let Streaming::Progressive(_) = self.streaming else {
            return Ok(self.streaming);
        };
        if self.queue == 0 {
            return Err(Error::setting("--queue", 0, "at least 1"));
        }
        let horizon = positive("--predict-seconds", self.predict_seconds)?;
        if !(0.0..=1.0).contains(&self.belt_fill) {
            return Err(Error::setting(
                "--belt-fill",
                self.belt_fill,
                "a share in [0, 1]",
            ));
        }
        Ok(Streaming::Progressive(StreamSettings {
            queue_capacity: self.queue,
            square_share: self.belt_fill,
            prediction: self.predict.then_some(PredictionSettings {
                horizon,
                ..PredictionSettings::default()
            }),
        }))
    }
}

/// The scene and engine settings `fly`, `view` and `fb` share.
#[derive(Args, Debug)]
pub(super) struct SceneArgs {
    /// A built-in flight (overview, diagonal, low) or a TOML file of keyframes.
    #[arg(long, default_value = Builtin::Diagonal.name())]
    flight: String,
    #[command(flatten)]
    device: DeviceArgs,
    /// Memory limit as a percentage of available memory (Linux), as in the paper.
    #[arg(long, allow_negative_numbers = true, conflicts_with = "memory_mb")]
    memory_percent: Option<f64>,
    /// Of the memory limit, the most tile textures may take, MB (default: no separate cap).
    #[arg(long, allow_negative_numbers = true)]
    texture_mb: Option<f64>,
    /// Use the f32 reference pipeline instead of fixed point.
    #[arg(long)]
    float: bool,
    /// Power-of-two mask levels only (geometrical mipmapping) instead of every level.
    #[arg(long)]
    pow2_masks: bool,
    /// Importance weight of distance (the height weight is 1 minus it).
    #[arg(long, default_value_t = Weights::default().distance(), allow_negative_numbers = true)]
    distance_weight: f64,
    /// How cracks between tiles at different levels are hidden (docs/cracks.md).
    #[arg(long, value_parser = named::<CrackMode>(), default_value = CrackMode::default().name())]
    cracks: CrackMode,
    /// Morph the vertices coarser levels drop by distance, against popping (docs/cracks.md).
    #[arg(long, value_parser = named::<Geomorph>(), default_value = Geomorph::default().name())]
    geomorph: Geomorph,
    /// With --geomorph distance: vertices whose grid step spans fewer pixels than this are
    /// fully morphed, those spanning twice as many not at all.
    #[arg(long, default_value_t = Geomorph::DEFAULT_PIXELS, allow_negative_numbers = true)]
    geomorph_pixels: f64,
    #[command(flatten)]
    streaming: StreamingArgs,
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
    /// The scene over the archive `source_name` (read for the terrain the flight is scaled to,
    /// its requests bounded by `http`).
    pub(super) fn resolve(&self, source_name: &str, http: HttpOptions) -> Result<Scene> {
        let flight = flight_with(&self.flight, source_name, http)?;
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
            cracks: self.cracks,
            geomorph: match self.geomorph {
                Geomorph::Distance { .. } => Geomorph::Distance {
                    pixels: positive("--geomorph-pixels", self.geomorph_pixels)?,
                },
                Geomorph::Off => Geomorph::Off,
            },
            streaming: self.streaming.resolve()?,
            max_error: device.max_error()?,
            allocation: device.allocation,
            ..EngineSettings::default()
        };
        let clock = self.device.clock.with_slowdown(device.cpu_slowdown);
        engine.budget = device.budget(clock);
        if self.float {
            engine.render.precision = Precision::Float;
        }
        Ok(Scene {
            flight,
            engine,
            size: (device.width, device.height),
            color: device.color,
            depth: device.depth,
            target_fps: device.target_fps,
            clock,
            link: (!device.link.is_unlimited()).then_some(device.link),
        })
    }
}

/// The flight `name` (built in, or a TOML file) over the archive `source_name`.
pub(super) fn flight(name: &str, source_name: &str) -> Result<Flight> {
    flight_with(name, source_name, HttpOptions::default())
}

/// [`flight`], its requests bounded by `http`.
fn flight_with(name: &str, source_name: &str, http: HttpOptions) -> Result<Flight> {
    let reader = ArchiveReader::open(source::open_with(source_name, http)?)?;
    Flight::builtin_or_file(name, &TerrainFrame::new(reader.header()))
}

impl SceneArgs {
    /// Whether the flight runs on the wall clock.
    pub(super) fn wall_clock(&self) -> bool {
        !self.device.clock.is_simulated()
    }
}

/// Parses a library setting chosen by name: the possible values clap lists, in help and in
/// errors, are the library's names.
pub(super) fn named<T: Named + Send + Sync>() -> impl TypedValueParser<Value = T> {
    PossibleValuesParser::new(T::all().iter().map(Named::name)).try_map(|name| T::from_name(&name))
}

/// Parses the name of a built-in device profile.
pub(super) fn profile_name() -> PossibleValuesParser {
    PossibleValuesParser::new(DeviceProfile::BUILTIN)
}

/// The longest flight `--seconds` may ask for (a day).
const MAX_SECONDS: f64 = 86_400.0;

/// The flight length of `--frames N` or `--seconds S` (`None`: the whole flight); `S` must be
/// a positive number of seconds up to a day, so that the flight ends.
pub(super) fn length(frames: Option<u64>, seconds: Option<f64>) -> Result<Option<Length>> {
    Ok(match (frames, seconds) {
        (Some(n), _) => Some(Length::Frames(n)),
        (None, Some(s)) if s > 0.0 && s <= MAX_SECONDS => Some(Length::Seconds(s)),
        (None, Some(s)) => {
            return Err(Error::setting(
                "--seconds",
                s,
                format!("a positive number up to {MAX_SECONDS}"),
            ));
        }
        (None, None) => None,
    })
}

/// `value` of `flag` as a time, when it is a positive number of seconds up to a day.
pub(super) fn duration(flag: &'static str, value: f64) -> Result<std::time::Duration> {
    if value > 0.0 && value <= MAX_SECONDS {
        Ok(std::time::Duration::from_secs_f64(value))
    } else {
        Err(Error::setting(
            flag,
            value,
            format!("a positive number of seconds up to {MAX_SECONDS}"),
        ))
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

/// `WxH`, each side 1 ..= 8192.
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
