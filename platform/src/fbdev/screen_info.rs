//! Screen geometry and pixel format: the kernel's structures from linux/fb.h and the crate's
//! own [`ScreenInfo`], which a test can also build by hand.

use std::fs::File;
use std::path::Path;

use libc::{c_char, c_ulong};

use super::ioctl;
use crate::PlatformError;

/// `struct fb_bitfield`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct FbBitfield {
    pub offset: u32,
    pub length: u32,
    pub msb_right: u32,
}

/// `struct fb_var_screeninfo`: the mode.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct FbVarScreeninfo {
    pub xres: u32,
    pub yres: u32,
    pub xres_virtual: u32,
    pub yres_virtual: u32,
    pub xoffset: u32,
    pub yoffset: u32,
    pub bits_per_pixel: u32,
    pub grayscale: u32,
    pub red: FbBitfield,
    pub green: FbBitfield,
    pub blue: FbBitfield,
    pub transp: FbBitfield,
    pub nonstd: u32,
    pub activate: u32,
    pub height: u32,
    pub width: u32,
    pub accel_flags: u32,
    pub pixclock: u32,
    pub left_margin: u32,
    pub right_margin: u32,
    pub upper_margin: u32,
    pub lower_margin: u32,
    pub hsync_len: u32,
    pub vsync_len: u32,
    pub sync: u32,
    pub vmode: u32,
    pub rotate: u32,
    pub colorspace: u32,
    pub reserved: [u32; 4],
}

/// `struct fb_fix_screeninfo`: what the mode cannot change.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct FbFixScreeninfo {
    pub id: [c_char; 16],
    pub smem_start: c_ulong,
    pub smem_len: u32,
    pub type_: u32,
    pub type_aux: u32,
    pub visual: u32,
    pub xpanstep: u16,
    pub ypanstep: u16,
    pub ywrapstep: u16,
    pub line_length: u32,
    pub mmio_start: c_ulong,
    pub mmio_len: u32,
    pub accel: u32,
    pub capabilities: u16,
    pub reserved: [u16; 2],
}

/// FB_TYPE_PACKED_PIXELS: pixels one after another, not in planes.
const FB_TYPE_PACKED_PIXELS: u32 = 0;
/// FB_VISUAL_TRUECOLOR: pixel values are colours.
const FB_VISUAL_TRUECOLOR: u32 = 2;
/// FB_VISUAL_DIRECTCOLOR: pixel values index per-channel ramps (linear unless someone set them).
const FB_VISUAL_DIRECTCOLOR: u32 = 4;

/// Where one colour channel sits in a pixel value.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Bitfield {
    /// Bit offset from the least significant bit.
    pub offset: u32,
    /// Number of bits (0: the channel is absent).
    pub length: u32,
}

impl Bitfield {
    /// `length` bits starting at bit `offset`.
    pub const fn new(offset: u32, length: u32) -> Self {
        Self { offset, length }
    }
}

/// The visible screen and its pixel format, as the device reports it (or as a test sets it).
/// A pixel is a `bits_per_pixel`-bit integer in the machine's byte order; channels sit where
/// their bitfields say.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct ScreenInfo {
    /// Visible width in pixels.
    pub width: u32,
    /// Visible height in pixels.
    pub height: u32,
    /// Column of the visible area in the virtual screen (panning).
    pub xoffset: u32,
    /// Row of the visible area in the virtual screen (panning).
    pub yoffset: u32,
    /// 16, 24 or 32.
    pub bits_per_pixel: u32,
    /// Bytes from one row to the next (at least `width` pixels; drivers pad).
    pub line_length: u32,
    /// Red channel.
    pub red: Bitfield,
    /// Green channel.
    pub green: Bitfield,
    /// Blue channel.
    pub blue: Bitfield,
    /// Alpha channel (length 0 when there is none); written as opaque.
    pub transp: Bitfield,
}

impl ScreenInfo {
    /// Asks the device for its mode (FBIOGET_VSCREENINFO, FBIOGET_FSCREENINFO). Returns the
    /// screen and the length of its memory in bytes.
    pub(crate) fn query(file: &File, device: &Path) -> Result<(Self, usize), PlatformError> {
        let var: FbVarScreeninfo = ioctl::get(file).map_err(|source| PlatformError::Ioctl {
            device: device.to_path_buf(),
            request: <FbVarScreeninfo as ioctl::IoctlGet>::NAME,
            source,
        })?;
        let fix: FbFixScreeninfo = ioctl::get(file).map_err(|source| PlatformError::Ioctl {
            device: device.to_path_buf(),
            request: <FbFixScreeninfo as ioctl::IoctlGet>::NAME,
            source,
        })?;
        let unsupported = |detail: String| PlatformError::Unsupported {
            device: device.to_path_buf(),
            detail,
        };
        if fix.type_ != FB_TYPE_PACKED_PIXELS {
            return Err(unsupported(format!(
                "framebuffer type {} is not packed pixels",
                fix.type_
            )));
        }
        if fix.visual != FB_VISUAL_TRUECOLOR && fix.visual != FB_VISUAL_DIRECTCOLOR {
            return Err(unsupported(format!(
                "visual {} is not true colour (a palette screen?)",
                fix.visual
            )));
        }
        if var.grayscale != 0 {
            return Err(unsupported("the screen is in grayscale mode".into()));
        }
        for (name, field) in [
            ("red", var.red),
            ("green", var.green),
            ("blue", var.blue),
            ("alpha", var.transp),
        ] {
            if field.msb_right != 0 {
                return Err(unsupported(format!(
                    "the {name} channel has its most significant bit on the right"
                )));
            }
        }
        let field = |f: FbBitfield| Bitfield::new(f.offset, f.length);
        let info = Self {
            width: var.xres,
            height: var.yres,
            xoffset: var.xoffset,
            yoffset: var.yoffset,
            bits_per_pixel: var.bits_per_pixel,
            line_length: fix.line_length,
            red: field(var.red),
            green: field(var.green),
            blue: field(var.blue),
            transp: field(var.transp),
        };
        Ok((info, fix.smem_len as usize))
    }

    /// Bytes of screen memory from the start of the virtual screen to the end of the visible
    /// area's last row.
    pub(crate) fn mapped_len(&self) -> usize {
        self.line_length as usize * (self.yoffset as usize + self.height as usize)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_kernel_structures_have_the_kernels_sizes() {
        assert_eq!(std::mem::size_of::<FbBitfield>(), 12);
        assert_eq!(std::mem::size_of::<FbVarScreeninfo>(), 160);
        let (size, line_length) = if cfg!(target_pointer_width = "64") {
            (80, 48)
        } else {
            (68, 44)
        };
        assert_eq!(std::mem::size_of::<FbFixScreeninfo>(), size);
        assert_eq!(
            std::mem::offset_of!(FbFixScreeninfo, line_length),
            line_length
        );
    }
}
