//! `stripmask view`: the viewer in a desktop window; the options it shares with `fb`.

use clap::Args;
#[cfg(any(feature = "window", all(feature = "fbdev", target_os = "linux")))]
use stripmask::db::source::http::HttpOptions;
use stripmask::error::Result;
#[cfg(any(feature = "window", all(feature = "fbdev", target_os = "linux")))]
use stripmask::sim::viewer::{ViewerOptions, ViewerSummary};

use stripmask::sim::pose::PoseSource;

use super::args::SceneArgs;

/// What `view` and `fb` show: a window, or the Linux framebuffer.
#[derive(Args, Debug)]
pub(super) struct ViewArgs {
    /// An archive file or http:// URL.
    source: String,
    /// Stop after N frames (default: until Esc, the window closing, or Ctrl-C).
    #[arg(long)]
    frames: Option<u64>,
    /// Start with the HUD off (H toggles it).
    #[arg(long)]
    no_hud: bool,
    /// Steer the camera from a feed of poses: `stdin`, `udp:HOST:PORT` (one pose a datagram),
    /// or a recording to replay (a file). One pose a line: `TIME EAST NORTH ALTITUDE HEADING
    /// PITCH ROLL` (seconds; the archive's coordinates, metres; degrees clockwise from north, up,
    /// right wing down), `geo TIME LATITUDE LONGITUDE ALTITUDE HEADING PITCH ROLL` (degrees,
    /// heading from true north) on a georeferenced archive, or NMEA 0183 `$xxGGA` and `$xxRMC`
    /// sentences from a GPS.
    #[arg(long, value_name = "SOURCE")]
    pose_from: Option<PoseSource>,
    #[command(flatten)]
    scene: SceneArgs,
}

/// What the viewer shows: the scene resolved, the engine with its default (threaded) pager.
#[cfg(any(feature = "window", all(feature = "fbdev", target_os = "linux")))]
pub(super) fn viewer_options(a: &ViewArgs) -> Result<ViewerOptions> {
    let scene = a.scene.resolve(&a.source, HttpOptions::default())?;
    let mut engine = scene.engine;
    // A fetch thread on the wall clock; on the simulated clock (`--clock simulated`) fetches that
    // complete at reproducible frames, so that `--frames N` shows what `fly` draws at frame N - 1.
    if scene.clock.is_simulated() {
        engine.pager_mode = scene.clock.pager_mode(4);
    }
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
        poses: a.pose_from.clone(),
    })
}

/// Prints how many frames the viewer showed, and how fast.
#[cfg(any(feature = "window", all(feature = "fbdev", target_os = "linux")))]
pub(super) fn report_view(s: ViewerSummary) {
    say!(
        "{} frames in {:.1} s ({:.1} fps)",
        s.frames,
        s.seconds,
        s.frames as f64 / s.seconds.max(1e-9)
    );
}

/// Runs the viewer in a window until Esc or the window closes (or `--frames`).
#[cfg(feature = "window")]
pub(super) fn run(a: ViewArgs) -> Result<()> {
    let options = viewer_options(&a)?;
    let (w, h) = options.size;
    let mut window =
        stripmask_platform::WindowPresenter::open(&format!("stripmask: {}", a.source), w, h)?;
    report_view(stripmask::sim::viewer::run(&mut window, &options)?);
    Ok(())
}

/// Without windows: the error that says which feature it needs.
#[cfg(not(feature = "window"))]
pub(super) fn run(_: ViewArgs) -> Result<()> {
    Err(stripmask::Error::Unsupported {
        command: "`stripmask view`",
        needs: "the `window` feature",
    })
}
