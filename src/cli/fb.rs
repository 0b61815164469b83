//! `stripmask fb`: the viewer on the Linux framebuffer.

use std::path::PathBuf;

use clap::Args;
use stripmask::Named;
use stripmask::error::Result;
use stripmask_platform::Fit;

use super::args::named;
use super::view::ViewArgs;
#[cfg(all(feature = "fbdev", target_os = "linux"))]
use super::view::{report_view, viewer_options};
#[cfg(all(feature = "fbdev", target_os = "linux"))]
use stripmask::sim::viewer;

/// `fb`'s arguments: the viewer's, the framebuffer device, the fit and a keyboard.
#[derive(Args, Debug)]
pub(super) struct FbArgs {
    #[command(flatten)]
    view: ViewArgs,
    /// The framebuffer device.
    #[arg(long, default_value = "/dev/fb0")]
    device: PathBuf,
    /// Fit a frame that differs from the screen: centre it, or scale it to fill.
    #[arg(long, value_parser = named::<Fit>(), default_value = Fit::default().name())]
    fit: Fit,
    /// An evdev keyboard (e.g. /dev/input/event0) to fly with the viewer's keys.
    #[arg(long)]
    input: Option<PathBuf>,
    /// Draw frames of the screen's size straight into its memory while the HUD is off: no
    /// frame buffer and no copy, but the screen shows each frame as it is drawn.
    #[arg(long)]
    in_place: bool,
}

/// Runs the viewer on the framebuffer until Ctrl-C (or `--frames`).
#[cfg(all(feature = "fbdev", target_os = "linux"))]
pub(super) fn run(a: FbArgs) -> Result<()> {
    let options = viewer_options(&a.view)?;
    let mut screen =
        stripmask_platform::FbPresenter::open(&a.device, a.fit)?.with_in_place(a.in_place);
    if let Some(path) = &a.input {
        screen = screen.with_input(stripmask_platform::EvdevInput::open(path)?);
    }
    report_view(viewer::run(&mut screen, &options)?);
    Ok(())
}

/// Without the framebuffer: the error that says which feature it needs.
#[cfg(not(all(feature = "fbdev", target_os = "linux")))]
pub(super) fn run(_: FbArgs) -> Result<()> {
    Err(stripmask::Error::Unsupported {
        command: "`stripmask fb`",
        needs: "the `fbdev` feature (Linux only)",
    })
}
