//! Where stripmask frames go. The engine renders into a [`Framebuffer`] (RGB565 or RGBA8888) and
//! hands it to a [`Presenter`], which shows or stores it and reports what the user did since the
//! last frame as an [`Input`]. Three presenters:
//!
//! - [`PngFrames`]: every n-th frame as a PNG file; always built, the headless choice.
//! - `WindowPresenter` (cargo feature `window`): a desktop window through minifb's X11 backend.
//! - `FbPresenter` (cargo feature `fbdev`, Linux): the Linux framebuffer device, `/dev/fb0`.
//!
//! Beside them, `GpuTarget` (cargo feature `wgpu`, off by default) takes the same draws as the CPU
//! rasterizer through wgpu, as a reference for accuracy and a peer for speed.
//!
//! The [`Hud`] draws statistics and a minimap of the belts with tiny-skia into an [`Overlay`],
//! which a presenter composites over the frame while it converts pixels; when the HUD is off there
//! is no overlay and the conversion is the plain one. Frames are never scaled or converted twice:
//! each presenter maps its output pixels to frame pixels once ([`Fit`]), and composition works on
//! 8-bit RGB rows, so the same frame and overlay give the same bytes on every target.

mod compose;
mod error;
#[cfg(all(feature = "fbdev", target_os = "linux"))]
mod fbdev;
mod fit;
#[cfg(feature = "wgpu")]
mod gpu;
mod heap;
mod hud;
mod input;
mod png;
#[cfg(feature = "window")]
mod window;

pub use compose::compose_rgba;
pub use error::PlatformError;
#[cfg(all(feature = "fbdev", target_os = "linux"))]
pub use fbdev::{Bitfield, EvdevInput, FbPresenter, ScreenInfo};
pub use fit::Fit;
#[cfg(feature = "wgpu")]
pub use gpu::GpuTarget;
pub use heap::keep_large_blocks_apart;
pub use hud::{Hud, HudInfo, Minimap, MinimapCell, Overlay, PanelRect};
pub use input::{Command, Input, Motion};
pub use png::PngFrames;
#[cfg(feature = "window")]
pub use window::WindowPresenter;

use stripmask_raster::{DepthBuffer, Framebuffer, Surface};

/// A destination for finished frames.
pub trait Presenter {
    /// Shows (or stores) one frame, with the HUD overlay composited over it when there is one.
    fn present(&mut self, frame: &Framebuffer, hud: Option<&Overlay>) -> Result<(), PlatformError>;

    /// The screen's own memory as a [`Surface`] to draw the next frame straight into, its size
    /// the screen's and `depth` (the caller's, kept from frame to frame) its depth buffer; the
    /// frame shows as it is drawn and needs no `present`. `None` (what presenters without
    /// drawable memory give, and what a depth buffer of another size than the screen gets)
    /// means frames go through [`Presenter::present`].
    fn surface<'a>(
        &'a mut self,
        _depth: &'a mut DepthBuffer,
    ) -> Result<Option<Surface<'a>>, PlatformError> {
        Ok(None)
    }

    /// What the user did since the last call. Presenters without input devices report nothing.
    fn poll_input(&mut self) -> Input {
        Input::default()
    }
}
