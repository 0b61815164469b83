//! `stripmask demo`: the paper's PocketPC flyover in one command, headless or in a window.

use std::path::PathBuf;

use clap::Args;
use stripmask::Named;
use stripmask::error::Result;
use stripmask::sim::clock::Clock;
use stripmask::sim::demo::DemoOptions;
use stripmask::sim::fly::LiveView;
use stripmask_platform::Presenter;

use super::args::{StreamingArgs, length, named, profile_name};
use super::device::{Overrides, profile};

/// `demo`'s arguments: the device, the clock, how long, and whether to show a window.
#[derive(Args, Debug)]
pub(super) struct DemoArgs {
    /// Output folder: archive, stats.csv, frames and plots.
    #[arg(long, default_value_os_t = DemoOptions::default().out)]
    out: PathBuf,
    /// The elevation model (default: the Puget Sound 1k model carried in the program).
    #[arg(long)]
    dem: Option<PathBuf>,
    /// Device profile.
    #[arg(long, value_parser = profile_name(), default_value_t = DemoOptions::default().profile.name)]
    profile: String,
    /// A TOML device profile instead of a built-in one.
    #[arg(long, conflicts_with = "profile")]
    profile_file: Option<PathBuf>,
    #[command(flatten)]
    overrides: Overrides,
    /// simulated (reproducible) or wall (measured frame costs).
    #[arg(long, value_parser = named::<Clock>(), default_value = DemoOptions::default().clock.name())]
    clock: Clock,
    /// Stop after N frames (default: the whole flight).
    #[arg(long, conflicts_with = "seconds")]
    frames: Option<u64>,
    /// Stop after S seconds of flight time.
    #[arg(long, allow_negative_numbers = true)]
    seconds: Option<f64>,
    /// Keep one frame in K as PNG (0: none).
    #[arg(long, default_value_t = DemoOptions::default().every)]
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

/// Runs the demo, in a window when asked and one opens (headless, and an error, when not).
pub(super) fn run(a: DemoArgs) -> Result<()> {
    let options = DemoOptions {
        out: a.out,
        dem: a.dem,
        profile: profile(&a.profile, a.profile_file.as_deref(), &a.overrides)?,
        clock: a.clock,
        length: length(a.frames, a.seconds)?,
        every: a.every,
        progress: !a.quiet,
        streaming: a.streaming.resolve()?,
    };
    if !a.window {
        say!("{}", stripmask::sim::demo::run(&options)?);
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
            say!("{}", stripmask::sim::demo::run_live(&options, Some(live))?);
            Ok(())
        }
        Err(problem) => {
            eprintln!("stripmask demo: --window: {problem}; running headless");
            say!("{}", stripmask::sim::demo::run(&options)?);
            Err(problem)
        }
    }
}

/// A window for live frames, or why there is none.
#[cfg(feature = "window")]
fn open_window(title: &str, width: u32, height: u32) -> Result<Box<dyn Presenter>> {
    Ok(Box::new(stripmask_platform::WindowPresenter::open(
        title, width, height,
    )?))
}

#[cfg(not(feature = "window"))]
fn open_window(_: &str, _: u32, _: u32) -> Result<Box<dyn Presenter>> {
    Err(stripmask::Error::Unsupported {
        command: "`stripmask demo --window`",
        needs: "the `window` feature",
    })
}
