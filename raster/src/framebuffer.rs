//! A framebuffer that owns its colour and depth buffers, and readback for PNG output.

use image::RgbaImage;

use crate::RasterError;
use crate::depth_buffer::{DepthBuffer, DepthFormat};
use crate::layout::PixelLayout;
use crate::pixel::{PixelFormat, Rgb565, Rgba8888};
use crate::surface::{AsSurface, ColorMut, DepthMut, Rows, Surface, check_size};

/// Colour-buffer format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ColorFormat {
    /// 16-bit 5-6-5, the handheld's format.
    Rgb565,
    /// 32-bit, bytes R, G, B, A.
    Rgba8888,
}

/// Colour storage.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ColorBuffer {
    /// 5-6-5 pixels, row-major.
    Rgb565(Vec<u16>),
    /// RGBA pixels, row-major.
    Rgba8888(Vec<[u8; 4]>),
}

/// A render target that owns its memory: colour plus optional depth, `width * height` pixels,
/// row-major, top row first. The rasterizer draws into it through the [`crate::Surface`] it
/// lends ([`crate::AsSurface`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Framebuffer {
    width: u32,
    height: u32,
    color: ColorBuffer,
    depth: DepthBuffer,
}

impl Framebuffer {
    /// A black framebuffer with depth cleared to the far plane.
    pub fn new(
        width: u32,
        height: u32,
        color: ColorFormat,
        depth: DepthFormat,
    ) -> Result<Self, RasterError> {
        check_size(width, height)?;
        let n = width as usize * height as usize;
        let color = match color {
            ColorFormat::Rgb565 => ColorBuffer::Rgb565(vec![0; n]),
            ColorFormat::Rgba8888 => ColorBuffer::Rgba8888(vec![[0, 0, 0, 255]; n]),
        };
        let depth = DepthBuffer::new(width, height, depth);
        Ok(Self {
            width,
            height,
            color,
            depth,
        })
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Colour format.
    pub fn color_format(&self) -> ColorFormat {
        match self.color {
            ColorBuffer::Rgb565(_) => ColorFormat::Rgb565,
            ColorBuffer::Rgba8888(_) => ColorFormat::Rgba8888,
        }
    }

    /// Depth format.
    pub fn depth_format(&self) -> DepthFormat {
        match self.depth {
            DepthBuffer::None => DepthFormat::None,
            DepthBuffer::D16(_) => DepthFormat::D16,
            DepthBuffer::D32(_) => DepthFormat::D32,
        }
    }

    /// The colour pixels.
    pub fn color(&self) -> &ColorBuffer {
        &self.color
    }

    /// The depth values.
    pub fn depth(&self) -> &DepthBuffer {
        &self.depth
    }

    /// Fills the colour buffer.
    pub fn clear_color(&mut self, c: [u8; 3]) {
        self.as_surface().clear_color(c);
    }

    /// Resets depth to the far plane.
    pub fn clear_depth(&mut self) {
        self.as_surface().clear_depth();
    }

    /// Clears colour and depth.
    pub fn clear(&mut self, c: [u8; 3]) {
        self.as_surface().clear(c);
    }

    /// Colour of one pixel.
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 3] {
        let i = y as usize * self.width as usize + x as usize;
        match &self.color {
            ColorBuffer::Rgb565(p) => Rgb565::unpack(p[i]),
            ColorBuffer::Rgba8888(p) => Rgba8888::unpack(p[i]),
        }
    }

    /// The colour buffer as an RGBA image (RGB565 expanded by bit replication).
    pub fn to_rgba_image(&self) -> RgbaImage {
        let raw: Vec<u8> = match &self.color {
            ColorBuffer::Rgb565(p) => p
                .iter()
                .flat_map(|&v| {
                    let [r, g, b] = Rgb565::unpack(v);
                    [r, g, b, 255]
                })
                .collect(),
            ColorBuffer::Rgba8888(p) => p.iter().flat_map(|v| *v).collect(),
        };
        RgbaImage::from_raw(self.width, self.height, raw).expect("buffer size matches dimensions")
    }
}

impl From<ColorFormat> for PixelLayout {
    fn from(f: ColorFormat) -> Self {
        match f {
            ColorFormat::Rgb565 => Self::Rgb565,
            ColorFormat::Rgba8888 => Self::Rgba8888,
        }
    }
}

impl AsSurface for Framebuffer {
    fn as_surface(&mut self) -> Surface<'_> {
        let stride = self.width as usize;
        let color = match &mut self.color {
            ColorBuffer::Rgb565(p) => ColorMut::Rgb565(Rows { pixels: p, stride }),
            ColorBuffer::Rgba8888(p) => ColorMut::Rgba8888(Rows { pixels: p, stride }),
        };
        Surface::from_parts(
            self.width,
            self.height,
            color,
            DepthMut::of(&mut self.depth),
        )
    }
}

impl<'a> From<&'a mut Framebuffer> for Surface<'a> {
    fn from(fb: &'a mut Framebuffer) -> Self {
        fb.as_surface()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixed_point::MAX_DIMENSION;

    #[test]
    fn sizes_outside_the_supported_range_are_refused() {
        assert!(Framebuffer::new(0, 5, ColorFormat::Rgb565, DepthFormat::None).is_err());
        assert!(
            Framebuffer::new(MAX_DIMENSION + 1, 5, ColorFormat::Rgb565, DepthFormat::None).is_err()
        );
        assert!(Framebuffer::new(1, 1, ColorFormat::Rgb565, DepthFormat::D16).is_ok());
    }

    #[test]
    fn clear_and_readback_agree_in_both_formats() {
        for f in [ColorFormat::Rgb565, ColorFormat::Rgba8888] {
            let mut fb = Framebuffer::new(3, 2, f, DepthFormat::D32).unwrap();
            fb.clear([255, 0, 255]);
            let img = fb.to_rgba_image();
            assert_eq!(img.dimensions(), (3, 2));
            assert!(img.pixels().all(|p| p.0 == [255, 0, 255, 255]));
            assert_eq!(fb.pixel(2, 1), [255, 0, 255]);
        }
    }
}
