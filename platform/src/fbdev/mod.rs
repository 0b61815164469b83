//! The Linux framebuffer presenter: frames drawn straight into `/dev/fb*`'s mapped memory when
//! the screen's pixel format is one the rasterizer draws ([`Presenter::surface`]), otherwise
//! converted into it from our framebuffer ([`Presenter::present`]).

mod console;
mod evdev;
mod ioctl;
mod mapping;
mod pixel_layout;
mod screen_info;
mod sigint;

pub use evdev::EvdevInput;
pub use screen_info::{Bitfield, ScreenInfo};

use std::fs::File;
use std::path::{Path, PathBuf};

use stripmask_raster::{DepthBuffer, Framebuffer, Surface};

use crate::compose::RowReader;
use crate::fit::Placement;
use crate::{Fit, Input, Overlay, PlatformError, Presenter};
use console::Console;
use mapping::Mapping;
use pixel_layout::PixelLayout;
use sigint::SigintGuard;

/// Frames on a Linux framebuffer device. Opened with [`FbPresenter::open`], it puts the
/// console in graphics mode (when run from a virtual terminal) and turns Ctrl-C into
/// [`Input::quit`]; dropping it restores both. Frames of another size than the screen are
/// placed by a [`Fit`]; the screen outside the frame is black.
#[derive(Debug)]
pub struct FbPresenter {
    device: PathBuf,
    info: ScreenInfo,
    layout: PixelLayout,
    fit: Fit,
    map: Mapping,
    /// Where the last frame went, reused while the frame size stays.
    placement: Option<Placement>,
    /// One packed output row.
    row: Vec<u8>,
    console: Option<Console>,
    sigint: Option<SigintGuard>,
    /// A keyboard, if one was given.
    input: Option<EvdevInput>,
    /// Whether frames may be drawn straight into the visible screen ([`Presenter::surface`]).
    in_place: bool,
}

impl FbPresenter {
    /// Opens a framebuffer device such as `/dev/fb0`, reads its mode and maps its memory.
    pub fn open(device: impl AsRef<Path>, fit: Fit) -> Result<Self, PlatformError> {
        let device = device.as_ref();
        let file = open_device(device)?;
        let (info, memory_len) = ScreenInfo::query(&file, device)?;
        if memory_len < info.mapped_len() {
            return Err(PlatformError::Unsupported {
                device: device.to_path_buf(),
                detail: format!(
                    "{memory_len} bytes of screen memory hold fewer than {} rows of {} bytes",
                    info.yoffset + info.height,
                    info.line_length
                ),
            });
        }
        let mut presenter = Self::with_file(file, device, info, fit)?;
        presenter.console = Console::take_over();
        presenter.sigint = SigintGuard::install().ok();
        Ok(presenter)
    }

    /// Writes into `device`, any file at least as long as `info` needs, as if it were a screen
    /// described by `info`: no ioctl, no console, no Ctrl-C handler. For tests and for
    /// devices whose mode is known from elsewhere.
    pub fn with_screen_info(
        device: impl AsRef<Path>,
        info: ScreenInfo,
        fit: Fit,
    ) -> Result<Self, PlatformError> {
        let device = device.as_ref();
        let file = open_device(device)?;
        let len = file
            .metadata()
            .map_err(|source| PlatformError::DeviceOpen {
                device: device.to_path_buf(),
                source,
                hint: "",
            })?
            .len();
        if len < info.mapped_len() as u64 {
            return Err(PlatformError::Unsupported {
                device: device.to_path_buf(),
                detail: format!(
                    "{len} bytes are fewer than the {} the screen needs",
                    info.mapped_len()
                ),
            });
        }
        Self::with_file(file, device, info, fit)
    }

    fn with_file(
        file: File,
        device: &Path,
        info: ScreenInfo,
        fit: Fit,
    ) -> Result<Self, PlatformError> {
        let layout = PixelLayout::new(&info).map_err(|detail| PlatformError::Unsupported {
            device: device.to_path_buf(),
            detail,
        })?;
        let len = info.mapped_len();
        let map = Mapping::new(&file, len).map_err(|source| PlatformError::Map {
            device: device.to_path_buf(),
            len,
            source,
        })?;
        Ok(Self {
            device: device.to_path_buf(),
            info,
            layout,
            fit,
            map,
            placement: None,
            row: Vec::new(),
            console: None,
            sigint: None,
            input: None,
            in_place: false,
        })
    }

    /// The screen's geometry and pixel format.
    pub fn screen_info(&self) -> &ScreenInfo {
        &self.info
    }

    /// The visible size in pixels: render at this size to fill the screen one to one.
    pub fn size(&self) -> (u32, u32) {
        (self.info.width, self.info.height)
    }

    /// The device path.
    pub fn device(&self) -> &Path {
        &self.device
    }

    /// Paints the whole visible area black.
    fn clear(&mut self) {
        let bpp = self.layout.bytes();
        self.row.resize(self.info.width as usize * bpp, 0);
        for px in self.row.chunks_exact_mut(bpp) {
            self.layout.write([0, 0, 0], px);
        }
        for y in 0..self.info.height {
            let at = offset(&self.info, bpp, 0, y);
            self.map.bytes_mut()[at..at + self.row.len()].copy_from_slice(&self.row);
        }
    }
}

/// Byte offset of visible pixel (`x`, `y`) in the mapping.
fn offset(info: &ScreenInfo, bpp: usize, x: u32, y: u32) -> usize {
    (info.yoffset + y) as usize * info.line_length as usize + (info.xoffset + x) as usize * bpp
}

/// Opens a device (or stand-in file) for reading and writing, naming it and the likely fix.
fn open_device(device: &Path) -> Result<File, PlatformError> {
    File::options()
        .read(true)
        .write(true)
        .open(device)
        .map_err(|source| {
            let hint = match source.kind() {
                std::io::ErrorKind::PermissionDenied => {
                    " (add the user to the video group, or run as root)"
                }
                std::io::ErrorKind::NotFound => {
                    " (is a framebuffer driver loaded? see ls /dev/fb*)"
                }
                _ => "",
            };
            PlatformError::DeviceOpen {
                device: device.to_path_buf(),
                source,
                hint,
            }
        })
}

impl FbPresenter {
    /// Reads keys from `input` (an evdev keyboard): the viewer's key table, as in the window.
    pub fn with_input(mut self, input: EvdevInput) -> Self {
        self.input = Some(input);
        self
    }

    /// Lends the visible screen's memory to draw frames straight into ([`Presenter::surface`]):
    /// no frame-sized buffer and no copy, but the screen shows each frame as it is drawn (near
    /// tiles first, then the far ones), so a reader of the screen may catch a frame half drawn.
    /// Off, frames are drawn aside and copied whole.
    pub fn with_in_place(mut self, on: bool) -> Self {
        self.in_place = on;
        self
    }
}

impl Presenter for FbPresenter {
    fn present(&mut self, frame: &Framebuffer, hud: Option<&Overlay>) -> Result<(), PlatformError> {
        let size = (frame.width(), frame.height());
        if self.placement.as_ref().is_none_or(|p| p.frame != size) {
            self.clear();
            let output = (self.info.width, self.info.height);
            self.placement = Some(Placement::new(size, output, self.fit));
        }
        let Self {
            info,
            layout,
            map,
            placement,
            row,
            ..
        } = self;
        let placement = placement.as_ref().expect("placed above");
        let bpp = layout.bytes();
        row.resize(placement.columns.len() * bpp, 0);
        let mut reader = RowReader::new(frame, hud);
        for (dy, &sy) in placement.rows.iter().enumerate() {
            let src = reader.row(sy);
            for (px, &sx) in row.chunks_exact_mut(bpp).zip(&placement.columns) {
                layout.write(src[sx as usize], px);
            }
            let at = offset(info, bpp, placement.x, placement.y + dy as u32);
            map.bytes_mut()[at..at + row.len()].copy_from_slice(row);
        }
        Ok(())
    }

    /// The visible screen memory, when the screen's pixel format is one the rasterizer draws
    /// (RGB565, BGR565, XRGB8888, XBGR8888; a 32-bit X or alpha byte is written as 0xFF) and
    /// its rows are whole pixels apart: no buffer of ours and no copy. Other formats give `None`
    /// and go through [`Presenter::present`], converted.
    fn surface<'a>(
        &'a mut self,
        depth: &'a mut DepthBuffer,
    ) -> Result<Option<Surface<'a>>, PlatformError> {
        if !self.in_place {
            return Ok(None);
        }
        let bpp = self.layout.bytes();
        let layout = self.layout.drawable();
        let Some(layout) = layout.filter(|_| (self.info.line_length as usize).is_multiple_of(bpp))
        else {
            return Ok(None);
        };
        let (width, height) = (self.info.width, self.info.height);
        let pixels = width as usize * height as usize;
        if depth.len_for(pixels) != pixels {
            // Frames of another size than the screen are placed by `present`.
            return Ok(None);
        }
        // The next `present` places its frame again and clears around it.
        self.placement = None;
        let start = offset(&self.info, bpp, 0, 0);
        let stride = self.info.line_length as usize;
        let memory = &mut self.map.bytes_mut()[start..];
        Ok(Some(
            Surface::new(memory, width, height, stride, layout)?.with_depth(depth)?,
        ))
    }

    fn poll_input(&mut self) -> Input {
        let mut input = match self.input.as_mut().map(EvdevInput::poll) {
            Some(Ok(input)) => input,
            Some(Err(e)) => {
                // An unplugged keyboard ends keyboard input, not the flight.
                eprintln!("{e}; keyboard input stops");
                self.input = None;
                Input::default()
            }
            None => Input::default(),
        };
        input.quit |= self.sigint.is_some() && sigint::interrupted();
        input
    }
}
