//! The crate's one error type.

use std::path::PathBuf;

use thiserror::Error;

/// What can go wrong while presenting.
#[derive(Debug, Error)]
pub enum PlatformError {
    /// A frame file could not be written.
    #[error("{path}: {source}")]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        source: image::ImageError,
    },
    /// The output folder could not be created.
    #[error("{path}: {source}")]
    Folder {
        /// The folder.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// No X display to open a window on.
    #[error("no X display: set DISPLAY or run under xvfb-run")]
    NoDisplay,
    /// The window system refused a window or a frame.
    #[error("window on display {display:?}: {message}")]
    Window {
        /// The value of DISPLAY.
        display: String,
        /// What the window system said.
        message: String,
    },
    /// The framebuffer device could not be opened.
    #[error("{device}: cannot open the framebuffer device: {source}{hint}")]
    DeviceOpen {
        /// The device path.
        device: PathBuf,
        /// Why.
        source: std::io::Error,
        /// What to try, if there is an obvious fix (may be empty).
        hint: &'static str,
    },
    /// The device refused a request: usually it is not a framebuffer device at all.
    #[error("{device}: {request} failed: {source} (is this a framebuffer device?)")]
    Ioctl {
        /// The device path.
        device: PathBuf,
        /// The request's name, e.g. `FBIOGET_VSCREENINFO`.
        request: &'static str,
        /// The error the kernel returned (ENOTTY for a regular file).
        source: std::io::Error,
    },
    /// The screen's pixel format or geometry is not one this crate can write.
    #[error("{device}: unsupported screen: {detail}")]
    Unsupported {
        /// The device path.
        device: PathBuf,
        /// What exactly.
        detail: String,
    },
    /// The input device could not be opened.
    #[error("{path}: cannot open the input device: {source}")]
    InputOpen {
        /// The device path.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// Reading the input device failed (for example, it was unplugged).
    #[error("{path}: cannot read input events: {source}")]
    InputRead {
        /// The device path.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// Mapping the device's memory failed.
    #[error("{device}: cannot map {len} bytes of screen memory: {source}")]
    Map {
        /// The device path.
        device: PathBuf,
        /// The length asked for.
        len: usize,
        /// Why.
        source: std::io::Error,
    },
    /// The rasterizer's inputs were refused (the GPU target checks them as the CPU does).
    #[error(transparent)]
    Raster(#[from] stripmask_raster::RasterError),
    /// No GPU adapter, not even a software one.
    #[cfg(feature = "wgpu")]
    #[error(
        "no GPU adapter: {detail} (without a GPU, install Mesa's Vulkan rasterizer: \
         apt-get install mesa-vulkan-drivers libvulkan1)"
    )]
    NoGpuAdapter {
        /// What wgpu said.
        detail: String,
    },
    /// The GPU refused a resource or a command, or lost the device.
    #[cfg(feature = "wgpu")]
    #[error("GPU adapter {adapter}: {message}")]
    Gpu {
        /// The adapter, as `GpuTarget::adapter_name` gives it.
        adapter: String,
        /// What went wrong.
        message: String,
    },
}
