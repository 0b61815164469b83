//! `stripmask fly`: a headless flight with statistics, frames and plots.

use std::path::PathBuf;

use clap::Args;
use stripmask::error::Result;
use stripmask::sim::fly::{FlyOptions, Length, fly};

use super::args::SceneArgs;

#[derive(Args, Debug)]
pub(super) struct FlyArgs {
    /// An archive file or http:// URL.
    pub(super) source: String,
    /// Stop after N frames (default: the whole flight).
    #[arg(long, conflicts_with = "seconds")]
    pub(super) frames: Option<u64>,
    /// Stop after S seconds of flight time.
    #[arg(long)]
    pub(super) seconds: Option<f64>,
    /// Output folder for stats.csv and frames.
    #[arg(long, default_value = "stripmask-fly")]
    pub(super) out: PathBuf,
    /// Keep one frame in K as PNG (0: none).
    #[arg(long, default_value_t = 10)]
    pub(super) every: u64,
    /// Draw the HUD (statistics and belt minimap) into the kept frames.
    #[arg(long)]
    pub(super) hud: bool,
    /// No progress bar.
    #[arg(short, long)]
    pub(super) quiet: bool,
    /// Do not draw the report's plots at the end.
    #[arg(long)]
    pub(super) no_plots: bool,
    #[command(flatten)]
    pub(super) scene: SceneArgs,
}

pub(super) fn run(a: FlyArgs) -> Result<()> {
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
