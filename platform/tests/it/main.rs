//! The integration tests of `stripmask-platform`, one module per behaviour, linked into one
//! binary.

mod common;

mod evdev;
mod fbdev;
#[cfg(feature = "wgpu")]
mod gpu_compare;
mod hud;
mod painted_frames;
mod window_xvfb;
