//! `stripmask fly`: a headless flight with statistics, frames and plots.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use stripmask::db::source::http::HttpOptions;
use stripmask::error::{Error, Result};
use stripmask::sim::fly::{FlyOptions, default_deadline, fly};
use stripmask::{ErrorBound, Named};

use super::args::{SceneArgs, duration, length};

/// `fly`'s arguments: the archive, the scene, how long, and what to write.
#[derive(Args, Debug)]
pub(super) struct FlyArgs {
    /// An archive file or http:// URL.
    source: String,
    /// Stop after N frames (default: the whole flight).
    #[arg(long, conflicts_with = "seconds")]
    frames: Option<u64>,
    /// Stop after S seconds of flight time.
    #[arg(long, allow_negative_numbers = true)]
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
    /// Wall-clock seconds from the start by which every HTTP request must have ended, opening
    /// the archive included; later ones fail at once [default: with --seconds S on the wall
    /// clock, S + 2; otherwise none].
    #[arg(long, allow_negative_numbers = true)]
    deadline: Option<f64>,
    /// Seconds one HTTP request may take, its whole body included.
    #[arg(long, allow_negative_numbers = true,
          default_value_t = HttpOptions::default().timeout.as_secs_f64())]
    http_timeout: f64,
    #[command(flatten)]
    scene: SceneArgs,
}

/// Flies headless and prints the summary. Fails when the archive changed while it was read,
/// when no terrain could be drawn because fetches failed, and when reads of tiles failed their
/// checksums.
pub(super) fn run(a: FlyArgs) -> Result<()> {
    let started = Instant::now();
    let length = length(a.frames, a.seconds)?;
    let deadline = match a.deadline {
        Some(s) => Some(duration("--deadline", s)?),
        None => default_deadline(length, a.scene.wall_clock()),
    };
    let http = HttpOptions {
        timeout: duration("--http-timeout", a.http_timeout)?,
        deadline: deadline.map(|d| started + d),
    };
    let scene = a.scene.resolve(&a.source, http)?;
    let options = FlyOptions {
        source: a.source.clone(),
        flight: scene.flight,
        length,
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
        http,
    };
    let s = fly(&options)?;
    say!(
        "{} frames over {:.1} s of flight: median {:.1} fps (target {}), {:.0} triangles and \
         {:.2} ms per frame, screen error max {:.1} / mean {:.2} px (τ {}; the budget, shared \
         by {}, bound {:.0} % of frames), peak memory {:.1} of {:.1} MB, {:.2} MB downloaded -> {}\nholes: {}",
        s.frames,
        s.seconds,
        s.median_fps,
        scene.target_fps,
        s.mean_triangles,
        s.mean_frame_ms,
        s.max_error_px,
        s.mean_error_px,
        match scene.engine.max_error {
            ErrorBound::Off => "off".to_string(),
            ErrorBound::Pixels(px) => format!("{px} px"),
        },
        scene.engine.allocation.name(),
        100.0 * s.budget_share,
        s.peak_memory_bytes as f64 / 1e6,
        s.memory_limit_bytes as f64 / 1e6,
        s.downloaded_bytes as f64 / 1e6,
        a.out.join("stats.csv").display(),
        s.holes
    );
    let pixels = f64::from(scene.size.0) * f64::from(scene.size.1);
    say!(
        "drawn: {:.1} tiles and {:.2} triangles per pixel a frame on average; host: median \
         {:.3} ms of bookkeeping, {:.3} ms of paging and {:.3} ms of drawing a frame",
        s.mean_tiles,
        s.mean_triangles / pixels,
        s.host_bookkeeping_ms,
        s.host_paging_ms,
        s.host_draw_ms
    );
    if s.refused > 0 {
        say!(
            "refused: {} read(s) of tiles failed their checksums",
            s.refused
        );
    }
    if let Some(what) = s.archive_changed {
        return Err(Error::ArchiveChanged {
            name: a.source.clone(),
            what,
        });
    }
    if s.holes.first_frame_s.is_none() && (s.errors > 0 || s.in_flight > 0) {
        return Err(Error::NothingLoaded {
            name: a.source.clone(),
            frames: s.frames,
            errors: s.errors,
            first: s.first_errors,
            in_flight: s.in_flight,
        });
    }
    if s.refused > 0 {
        return Err(Error::ChecksumsRefused {
            name: a.source.clone(),
            refused: s.refused,
        });
    }
    Ok(())
}
