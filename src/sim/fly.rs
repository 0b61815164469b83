//! `stripmask fly`: a flight over an archive, headless, with per-frame statistics and frames.
//!
//! Flight time advances by each frame's cost as [`Clock`] tells it (measured bookkeeping and
//! drawing, or modelled; times the device's CPU slowdown; writing PNGs is not counted), so a slow
//! renderer covers the path in fewer frames, as on the real device. On the wall clock a frame
//! takes at least the time of one at twice the target rate ([`Clock::pace`]): no display shows
//! frames faster, and while tiles are on their way the flight does not spin through empty
//! frames. A [`LiveView`] shows the
//! frames as they are computed as well (`demo --window`).

use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressStyle};
use stripmask_platform::{Hud, PngFrames, Presenter};
use stripmask_raster::{ColorFormat, DepthFormat, Framebuffer};

use crate::db::source;
use crate::db::source::http::HttpOptions;
use crate::db::source::throttle::LinkProfile;
use crate::db::source::watch::{Watch, Watched};
use crate::engine::allocation::Allocation;
use crate::engine::camera::Camera;
use crate::engine::error_bound::Bound;
use crate::engine::paging::{PagerMode, PagerStats};
use crate::engine::viewport::Viewport;
use crate::engine::{Engine, EngineSettings, FrameReport, FrameTiming};
use crate::error::{Error, Result};
use crate::sim::clock::{Clock, connect};
use crate::sim::flight::Flight;
use crate::sim::holes::HoleTally;
use crate::sim::hud::hud_info;
use crate::sim::report;
use crate::sim::stats::{FrameRecord, StatsCsv};

/// When a flight stops.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Length {
    /// After this many frames.
    Frames(u64),
    /// After this many seconds of flight time.
    Seconds(f64),
}

/// What to fly, where to write it.
#[derive(Clone, Debug)]
pub struct FlyOptions {
    /// Archive path or URL.
    pub source: String,
    /// The path.
    pub flight: Flight,
    /// When to stop; `None` flies the whole path once.
    pub length: Option<Length>,
    /// Framebuffer size.
    pub size: (u32, u32),
    /// Colour format (RGB565 as on the handheld, or RGBA8888).
    pub color: ColorFormat,
    /// Depth buffer format.
    pub depth: DepthFormat,
    /// Engine settings.
    pub engine: EngineSettings,
    /// Output folder for `stats.csv` and frames.
    pub out: PathBuf,
    /// Keep one frame in `every` as PNG (0: none).
    pub every: u64,
    /// Draw the HUD (statistics and minimap) into the kept frames.
    pub hud: bool,
    /// Show a progress bar.
    pub progress: bool,
    /// Where frame costs come from. The simulated clock turns a threaded pager into a
    /// simulated one with the same queue depth.
    pub clock: Clock,
    /// The link tiles come over (`None`: the source as it is).
    pub link: Option<LinkProfile>,
    /// Draw the report's plots into `out` at the end.
    pub plots: bool,
    /// How long HTTP requests may take, and the run's deadline: a fetch still unanswered at
    /// the end of the flight is abandoned and counted in [`FlySummary::in_flight`].
    pub http: HttpOptions,
}

/// Where a flight is shown while it runs, besides the files it writes.
pub struct LiveView<'a> {
    /// The window (or any presenter) the frames go to, with the HUD when the flight draws one.
    /// Its quit input (Esc, closing the window) ends the flight early; what was flown is still
    /// written.
    pub presenter: &'a mut dyn Presenter,
    /// Show each frame when its flight time has passed on the wall clock, so that the flight
    /// plays at the device's pace; otherwise frames are shown as fast as they are drawn.
    pub real_time: bool,
}

/// A run's summary.
#[derive(Clone, Debug, PartialEq)]
pub struct FlySummary {
    /// Frames rendered.
    pub frames: u64,
    /// Flight seconds covered.
    pub seconds: f64,
    /// Median frame rate.
    pub median_fps: f64,
    /// Mean triangles per frame.
    pub mean_triangles: f64,
    /// Mean time spent on a frame (as `stats.csv`'s `frame_ms`), milliseconds.
    pub mean_frame_ms: f64,
    /// The largest geometric error of a drawn tile on screen over the flight, pixels.
    pub max_error_px: f64,
    /// The mean over the frames of each frame's largest error on screen, pixels.
    pub mean_error_px: f64,
    /// Fraction of the frames whose detail the triangle budget capped (the rest: τ).
    pub budget_share: f64,
    /// Peak accounted memory, bytes.
    pub peak_memory_bytes: usize,
    /// The memory limit, bytes.
    pub memory_limit_bytes: usize,
    /// Bytes downloaded.
    pub downloaded_bytes: u64,
    /// Frames with holes and why, the first frame, the first without a hole, the top.
    pub holes: HoleTally,
    /// Fetches that failed (tiles and the top).
    pub errors: u64,
    /// The messages of the first failures, each naming its tile (at most
    /// [`crate::engine::paging::FIRST_ERRORS`]).
    pub first_errors: Vec<String>,
    /// Fetches (tiles and the top) still on their way when the flight ended, abandoned.
    pub in_flight: usize,
    /// Median host time of a frame's bookkeeping (cut, importance, budget, masks, the draw
    /// list), milliseconds measured on this machine whatever the clock: not part of
    /// `stats.csv`, which repeats byte for byte.
    pub host_bookkeeping_ms: f64,
    /// Median host time of the pager's update at a frame's start, milliseconds, measured
    /// likewise: on the simulated clock it includes the tiles fetched and decoded on the
    /// frame's thread.
    pub host_paging_ms: f64,
    /// Median host time of a frame's drawing, milliseconds, measured likewise.
    pub host_draw_ms: f64,
    /// Mean tiles drawn per frame.
    pub mean_tiles: f64,
    /// Reads of tiles (or of the top) whose bytes failed their checksums.
    pub refused: u64,
    /// What showed that the archive changed while it was read, which ended the flight there.
    pub archive_changed: Option<String>,
}

impl FlySummary {
    /// The summary without the host's timings, which vary from run to run: what repeats byte
    /// for byte on the simulated clock.
    pub fn repeatable(&self) -> FlySummary {
        FlySummary {
            host_bookkeeping_ms: 0.0,
            host_paging_ms: 0.0,
            host_draw_ms: 0.0,
            ..self.clone()
        }
    }
}

/// What a flight's requests get beyond its length on the wall clock before its deadline.
pub const DEADLINE_GRACE: Duration = Duration::from_secs(2);

/// The deadline of a flight of `length`, from its start, when none is given: on the wall clock
/// a flight of S seconds ends about S seconds after it started, so its requests have S plus
/// [`DEADLINE_GRACE`]; a flight of frames, or on the simulated clock (whose flight time is not
/// the wall's), has none.
pub fn default_deadline(length: Option<Length>, wall_clock: bool) -> Option<Duration> {
    match length {
        Some(Length::Seconds(s)) if wall_clock => Duration::try_from_secs_f64(s)
            .ok()
            .and_then(|d| d.checked_add(DEADLINE_GRACE)),
        _ => None,
    }
}

/// Flies `o.flight` and writes `stats.csv` (and frames) into `o.out`.
pub fn fly(o: &FlyOptions) -> Result<FlySummary> {
    fly_live(o, None)
}

/// [`fly`], showing the frames in `live` as well when given.
pub fn fly_live(o: &FlyOptions, mut live: Option<LiveView<'_>>) -> Result<FlySummary> {
    let out_name = o.out.display().to_string();
    std::fs::create_dir_all(&o.out).map_err(|e| Error::io(&out_name, e))?;
    let mut csv = StatsCsv::create(&o.out.join("stats.csv"))?;
    let mut frames = if o.every > 0 {
        Some(PngFrames::new(o.out.join("frames"), o.every)?)
    } else {
        None
    };
    let (w, h) = o.size;
    let mut fb = Framebuffer::new(w, h, o.color, o.depth)?;
    let (mut engine, watch) = flight_engine(o)?;
    let length = o
        .length
        .unwrap_or(Length::Seconds(o.flight.duration().max(f64::MIN_POSITIVE)));
    let bar = progress_bar(o.progress, length);
    let mut hud = Hud::new(o.hud);
    let started = Instant::now();
    let mut tally = Tally::default();
    // A changed archive ends the flight: what is still to come would only fail its checksums.
    while !tally.reached(length)
        && watch.changed().is_none()
        && !live.as_mut().is_some_and(|l| l.presenter.poll_input().quit)
    {
        let t = tally.t;
        let (eye, target) = o.flight.at(t);
        let origin = engine.terrain().origin;
        let camera = Camera {
            roll: o.flight.roll_at(t),
            ..engine.camera(origin + eye, origin + target, o.flight.above_ground)
        };
        engine.set_time(t);
        let report = engine.render(&camera, &mut fb)?;
        let cost = o.clock.frame_seconds(&report);
        engine.record_frame(cost, report.draw.triangles as usize);
        let record = frame_record(
            tally.frames,
            t,
            cost,
            (o.engine.budget.target_fps, o.engine.max_error.pixels()),
            &report,
        );
        csv.write(&record)?;
        if frames.is_some() || live.is_some() {
            let info = hud_info(&engine, &report, record.fps);
            let overlay = hud.render(&info, w, h);
            if let Some(frames) = frames.as_mut() {
                frames.present(&fb, overlay)?;
            }
            if let Some(live) = live.as_mut() {
                if live.real_time {
                    let due = Duration::from_secs_f64(t);
                    std::thread::sleep(due.saturating_sub(started.elapsed()));
                }
                live.presenter.present(&fb, overlay)?;
            }
        }
        let seconds = o.clock.pace(cost, o.engine.budget.target_fps);
        tally.add(&record, &report, seconds);
        bar.set_position(match length {
            Length::Frames(_) => tally.frames,
            Length::Seconds(_) => (tally.t * 10.0) as u64,
        });
    }
    bar.finish_and_clear();
    csv.finish()?;
    if o.plots {
        report::draw(&o.out)?;
    }
    Ok(tally.summary(&engine, &watch))
}

/// The engine of a flight, reading its tiles over the flight's link, and the watch on its
/// source. The simulated clock turns a threaded pager into a simulated one with the same queue
/// depth.
fn flight_engine(o: &FlyOptions) -> Result<(Engine, Arc<Watch>)> {
    let mut settings = o.engine;
    if let (Clock::Simulated { .. }, PagerMode::Threaded { queue_depth }) =
        (o.clock, settings.pager_mode)
    {
        settings.pager_mode = PagerMode::Simulated { queue_depth };
    }
    // The flight tells the budget each frame's time by its clock: the device's, or the host's.
    settings.frame_timing = FrameTiming::Told;
    // A flight's eye is placed over ground that may not be held yet.
    settings.lift_to_clearance = true;
    let (watched, watch) = Watched::new(source::open_with(&o.source, o.http)?);
    let (source, meter) = connect(Box::new(watched), o.link, &o.clock);
    let mut engine = Engine::new(source, settings, Viewport::new(o.size.0, o.size.1))?;
    if let Some(meter) = meter {
        engine.set_transfer_clock(meter);
    }
    Ok((engine, watch))
}

/// The `stats.csv` line of frame number `frame`, drawn at flight time `t` in `seconds` (its
/// cost, before any pacing), aiming at `(target fps, τ in pixels)`.
fn frame_record(
    frame: u64,
    t: f64,
    seconds: f64,
    (target_fps, tau_px): (f64, f64),
    report: &FrameReport,
) -> FrameRecord {
    FrameRecord {
        frame,
        time_s: t,
        frame_ms: seconds * 1e3,
        fps: 1.0 / seconds.max(1e-9),
        target_fps,
        budget: report.budget as u64,
        triangles: report.triangles as u64,
        fragments: report.draw.fragments,
        rendered_tiles: report.rendered_tiles as u64,
        loaded_tiles: report.pager.loaded_tiles as u64,
        memory_bytes: report.pager.memory_bytes as u64,
        memory_limit_bytes: report.pager.memory_limit_bytes as u64,
        downloaded_bytes: report.pager.downloaded_bytes,
        downloads: report.pager.fetches,
        complete_belts: report.pager.complete_belts.map_or(0, |d| u64::from(d) + 1),
        fetching: report.pager.fetching as u64,
        holes: report.holes as u64,
        top_bytes: report.pager.top_bytes as u64,
        tau_px,
        error_px: report.max_error_px,
        budget_binds: u64::from(report.bound == Bound::Budget),
        by_error: u64::from(report.allocation == Allocation::Error),
    }
}

/// A flight so far: its clock, and what the summary needs of the frames drawn.
#[derive(Default)]
struct Tally {
    /// Flight time, seconds.
    t: f64,
    frames: u64,
    fps: Vec<f64>,
    triangles: u64,
    holes: HoleTally,
    frame_ms: f64,
    max_error_px: f64,
    error_px: f64,
    budget_frames: u64,
    last_stats: Option<PagerStats>,
    bookkeeping_ms: Vec<f64>,
    paging_ms: Vec<f64>,
    draw_ms: Vec<f64>,
    tiles: u64,
}

impl Tally {
    /// Whether the flight has flown `length`.
    fn reached(&self, length: Length) -> bool {
        match length {
            Length::Frames(n) => self.frames >= n,
            Length::Seconds(s) => self.t >= s,
        }
    }

    /// Counts the frame of `record` and `report`, which took `seconds` of flight time (paced).
    fn add(&mut self, record: &FrameRecord, report: &FrameReport, seconds: f64) {
        self.holes.add(self.t, report);
        self.fps.push(record.fps);
        self.triangles += record.triangles;
        self.frame_ms += record.frame_ms;
        self.max_error_px = self.max_error_px.max(record.error_px);
        self.error_px += record.error_px;
        self.budget_frames += record.budget_binds;
        self.last_stats = Some(report.pager);
        self.bookkeeping_ms.push(report.bookkeeping_seconds * 1e3);
        self.paging_ms.push(report.paging_seconds * 1e3);
        self.draw_ms.push(report.draw_seconds * 1e3);
        self.tiles += report.rendered_tiles as u64;
        self.t += seconds;
        self.frames += 1;
    }

    /// The summary of the flight `engine` flew.
    fn summary(mut self, engine: &Engine, watch: &Watch) -> FlySummary {
        let median = |v: &mut Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v.get(v.len() / 2).copied().unwrap_or(0.0)
        };
        let host_bookkeeping_ms = median(&mut self.bookkeeping_ms);
        let host_paging_ms = median(&mut self.paging_ms);
        let host_draw_ms = median(&mut self.draw_ms);
        self.fps.sort_by(f64::total_cmp);
        let stats = self.last_stats.unwrap_or_else(|| engine.pager().stats());
        let frames = self.frames.max(1) as f64;
        FlySummary {
            frames: self.frames,
            seconds: self.t,
            median_fps: self.fps.get(self.fps.len() / 2).copied().unwrap_or(0.0),
            mean_triangles: self.triangles as f64 / frames,
            mean_frame_ms: self.frame_ms / frames,
            max_error_px: self.max_error_px,
            mean_error_px: self.error_px / frames,
            budget_share: self.budget_frames as f64 / frames,
            peak_memory_bytes: stats.memory_peak_bytes,
            memory_limit_bytes: stats.memory_limit_bytes,
            downloaded_bytes: stats.downloaded_bytes,
            holes: self.holes,
            errors: stats.errors,
            first_errors: engine.pager().first_errors().to_vec(),
            in_flight: in_flight(&stats),
            host_bookkeeping_ms,
            host_paging_ms,
            host_draw_ms,
            mean_tiles: self.tiles as f64 / frames,
            refused: watch.refused(),
            archive_changed: watch.changed().map(str::to_string),
        }
    }
}

/// Fetches `stats` says are on their way: tiles, and the top while its bytes are reserved and
/// none of its tiles has arrived.
fn in_flight(stats: &PagerStats) -> usize {
    stats.fetching + usize::from(stats.top_bytes > 0 && stats.top_tiles == 0)
}

fn progress_bar(show: bool, length: Length) -> ProgressBar {
    if !show {
        return ProgressBar::hidden();
    }
    let (len, unit) = match length {
        Length::Frames(n) => (n, "frames"),
        Length::Seconds(s) => ((s * 10.0).ceil() as u64, "ds of flight"),
    };
    ProgressBar::new(len).with_style(
        ProgressStyle::with_template(&format!(
            "{{elapsed_precise}} [{{bar:40}}] {{pos}}/{{len}} {unit} {{eta}}"
        ))
        .expect("valid template")
        .progress_chars("=> "),
    )
}
