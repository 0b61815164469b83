//! A render target in memory the caller owns: a mapped `/dev/fb0`, a window toolkit's buffer, a
//! shared-memory surface. Every draw goes through a [`Surface`]; a [`crate::Framebuffer`]
//! lends one over its own buffers.

use crate::depth_buffer::{DepthBuffer, DepthFormat};
use crate::error::{RasterError, SurfaceError};
use crate::fixed_point::MAX_DIMENSION;
use crate::layout::{
    PixelLayout, rgba_to_xbgr, rgba_to_xrgb, swap_565, xbgr_to_rgba, xrgb_to_rgba,
};
use crate::pixel::{PixelFormat, Rgb565, Rgba8888};

/// A picture to draw into: `width x height` pixels of colour in a [`PixelLayout`], rows
/// `stride` bytes apart in borrowed memory, and optionally a borrowed depth buffer of one value
/// per pixel, row-major without padding. Bytes between rows (past a row's last pixel) are never
/// read or written.
///
/// The memory must be aligned to the layout's word ([`PixelLayout::alignment`]: mapped screen
/// memory and any allocation of `u16`s or `u32`s are) so that the rasterizer copies whole words.
///
/// ```
/// use stripmask_raster::*;
/// let (width, height, stride) = (64, 48, 64 * 4 + 16);
/// // The caller's memory: here words, so that it is aligned for XRGB8888.
/// let mut screen = vec![0u32; stride / 4 * height as usize];
/// let mut depth = DepthBuffer::new(width, height, DepthFormat::D16);
/// let memory: &mut [u8] = bytemuck::cast_slice_mut(&mut screen);
/// let mut surface = Surface::new(memory, width, height, stride, PixelLayout::Xrgb8888)?
///     .with_depth(&mut depth)?;
/// surface.clear([0, 0, 255]);
/// assert_eq!(surface.pixel(5, 5), [0, 0, 255]);
/// assert_eq!(screen[5 * stride / 4 + 5], 0xFF00_00FF);
/// # Ok::<(), RasterError>(())
/// ```
pub struct Surface<'a> {
    width: u32,
    height: u32,
    pub(crate) color: ColorMut<'a>,
    pub(crate) depth: DepthMut<'a>,
}

/// Colour memory in one element type: pixel (x, y) is `pixels[y * stride + x]`.
pub(crate) struct Rows<'a, T> {
    pub pixels: &'a mut [T],
    pub stride: usize,
}

impl<'a, T: bytemuck::Pod> Rows<'a, T> {
    /// `memory` as elements, rows `stride` elements apart; its length and start were checked
    /// to be whole, aligned elements (`Surface::new`).
    fn of(memory: &'a mut [u8], stride: usize) -> Self {
        Self {
            pixels: bytemuck::try_cast_slice_mut(memory).expect("checked length and alignment"),
            stride,
        }
    }
}

impl<T> Rows<'_, T> {
    fn reborrow(&mut self) -> Rows<'_, T> {
        Rows {
            pixels: self.pixels,
            stride: self.stride,
        }
    }

    /// Fills columns `0..width` of every row with `v`: the first row element by element, the
    /// others copied from it, which a core without vectors does a block of words at a time
    /// where it would store 16-bit pixels one by one.
    fn fill(&mut self, width: usize, v: T)
    where
        T: Copy,
    {
        if self.pixels.is_empty() {
            return;
        }
        let (first, rest) = self.pixels.split_at_mut(self.stride.min(self.pixels.len()));
        let first = &mut first[..width];
        first.fill(v);
        for row in rest.chunks_mut(self.stride) {
            row[..width].copy_from_slice(first);
        }
    }
}

/// A surface's colour memory, in its layout.
pub(crate) enum ColorMut<'a> {
    Rgb565(Rows<'a, u16>),
    Bgr565(Rows<'a, u16>),
    Xrgb8888(Rows<'a, u32>),
    Xbgr8888(Rows<'a, u32>),
    Rgba8888(Rows<'a, [u8; 4]>),
}

/// A surface's depth values, `width` to a row.
pub(crate) enum DepthMut<'a> {
    None,
    D16(&'a mut [u16]),
    D32(&'a mut [u32]),
}

impl<'a> Surface<'a> {
    /// `memory` as `width x height` pixels in `layout`, rows `stride` bytes apart, without
    /// depth. Refused: a side of 0 or above 8192, a stride shorter than a row or not a multiple
    /// of the pixel size, memory shorter than the last row's end or not aligned to the layout.
    pub fn new(
        memory: &'a mut [u8],
        width: u32,
        height: u32,
        stride: usize,
        layout: PixelLayout,
    ) -> Result<Self, RasterError> {
        check_size(width, height)?;
        let pixel = layout.bytes_per_pixel();
        let row = width as usize * pixel;
        if stride < row {
            return Err(SurfaceError::StrideTooSmall { stride, row }.into());
        }
        if !stride.is_multiple_of(pixel) {
            return Err(SurfaceError::StrideNotWhole { stride, pixel }.into());
        }
        let needed = (height as usize - 1)
            .checked_mul(stride)
            .and_then(|n| n.checked_add(row))
            .ok_or(SurfaceError::TooShort {
                needed: usize::MAX,
                got: memory.len(),
            })?;
        if memory.len() < needed {
            return Err(SurfaceError::TooShort {
                needed,
                got: memory.len(),
            }
            .into());
        }
        let address = memory.as_ptr() as usize;
        let align = layout.alignment();
        if !address.is_multiple_of(align) {
            return Err(SurfaceError::Misaligned { address, align }.into());
        }
        let memory = &mut memory[..needed];
        let stride = stride / pixel;
        let color = match layout {
            PixelLayout::Rgb565 => ColorMut::Rgb565(Rows::of(memory, stride)),
            PixelLayout::Bgr565 => ColorMut::Bgr565(Rows::of(memory, stride)),
            PixelLayout::Xrgb8888 => ColorMut::Xrgb8888(Rows::of(memory, stride)),
            PixelLayout::Xbgr8888 => ColorMut::Xbgr8888(Rows::of(memory, stride)),
            PixelLayout::Rgba8888 => ColorMut::Rgba8888(Rows::of(memory, stride)),
        };
        Ok(Self {
            width,
            height,
            color,
            depth: DepthMut::None,
        })
    }

    /// A surface of parts already checked to fit `width x height`.
    pub(crate) fn from_parts(
        width: u32,
        height: u32,
        color: ColorMut<'a>,
        depth: DepthMut<'a>,
    ) -> Self {
        Self {
            width,
            height,
            color,
            depth,
        }
    }

    /// The surface with `depth` as its depth buffer (the caller keeps it from frame to frame);
    /// refused unless it holds one value per pixel.
    pub fn with_depth(self, depth: &'a mut DepthBuffer) -> Result<Self, RasterError> {
        let expected = self.width as usize * self.height as usize;
        let got = depth.len_for(expected);
        if got != expected {
            return Err(SurfaceError::DepthSize { expected, got }.into());
        }
        Ok(Self {
            depth: DepthMut::of(depth),
            ..self
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

    /// The colour layout.
    pub fn layout(&self) -> PixelLayout {
        match self.color {
            ColorMut::Rgb565(_) => PixelLayout::Rgb565,
            ColorMut::Bgr565(_) => PixelLayout::Bgr565,
            ColorMut::Xrgb8888(_) => PixelLayout::Xrgb8888,
            ColorMut::Xbgr8888(_) => PixelLayout::Xbgr8888,
            ColorMut::Rgba8888(_) => PixelLayout::Rgba8888,
        }
    }

    /// Bytes from one row to the next.
    pub fn stride(&self) -> usize {
        let elements = match &self.color {
            ColorMut::Rgb565(r) | ColorMut::Bgr565(r) => r.stride,
            ColorMut::Xrgb8888(r) | ColorMut::Xbgr8888(r) => r.stride,
            ColorMut::Rgba8888(r) => r.stride,
        };
        elements * self.layout().bytes_per_pixel()
    }

    /// Depth format.
    pub fn depth_format(&self) -> DepthFormat {
        match self.depth {
            DepthMut::None => DepthFormat::None,
            DepthMut::D16(_) => DepthFormat::D16,
            DepthMut::D32(_) => DepthFormat::D32,
        }
    }

    /// Fills the colour of every pixel (not the bytes between rows).
    pub fn clear_color(&mut self, c: [u8; 3]) {
        let w = self.width as usize;
        let rgb565 = Rgb565::pack(c);
        let rgba = Rgba8888::pack(c);
        match &mut self.color {
            ColorMut::Rgb565(r) => r.fill(w, rgb565),
            ColorMut::Bgr565(r) => r.fill(w, swap_565(rgb565)),
            ColorMut::Xrgb8888(r) => r.fill(w, rgba_to_xrgb(rgba)),
            ColorMut::Xbgr8888(r) => r.fill(w, rgba_to_xbgr(rgba)),
            ColorMut::Rgba8888(r) => r.fill(w, rgba),
        }
    }

    /// Resets depth to the far plane.
    pub fn clear_depth(&mut self) {
        match &mut self.depth {
            DepthMut::None => {}
            DepthMut::D16(d) => d.fill(u16::MAX),
            DepthMut::D32(d) => d.fill(u32::MAX),
        }
    }

    /// Clears colour and depth.
    pub fn clear(&mut self, c: [u8; 3]) {
        self.clear_color(c);
        self.clear_depth();
    }

    /// Colour of pixel (`x`, `y`); panics outside the surface.
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 3] {
        assert!(x < self.width && y < self.height, "pixel {x},{y} outside");
        let at = |stride: usize| y as usize * stride + x as usize;
        let [r, g, b, _] = match &self.color {
            ColorMut::Rgb565(c) => return Rgb565::unpack(c.pixels[at(c.stride)]),
            ColorMut::Bgr565(c) => return Rgb565::unpack(swap_565(c.pixels[at(c.stride)])),
            ColorMut::Xrgb8888(c) => xrgb_to_rgba(c.pixels[at(c.stride)]),
            ColorMut::Xbgr8888(c) => xbgr_to_rgba(c.pixels[at(c.stride)]),
            ColorMut::Rgba8888(c) => c.pixels[at(c.stride)],
        };
        [r, g, b]
    }
}

/// Refuses a picture with a side of 0 or above `MAX_DIMENSION`.
pub(crate) fn check_size(width: u32, height: u32) -> Result<(), RasterError> {
    if width == 0 || height == 0 || width > MAX_DIMENSION || height > MAX_DIMENSION {
        return Err(RasterError::FramebufferSize { width, height });
    }
    Ok(())
}

impl DepthMut<'_> {
    pub(crate) fn of(depth: &mut DepthBuffer) -> DepthMut<'_> {
        match depth {
            DepthBuffer::None => DepthMut::None,
            DepthBuffer::D16(d) => DepthMut::D16(d),
            DepthBuffer::D32(d) => DepthMut::D32(d),
        }
    }
}

impl std::fmt::Debug for Surface<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Surface")
            .field("width", &self.width)
            .field("height", &self.height)
            .field("stride", &self.stride())
            .field("layout", &self.layout())
            .field("depth", &self.depth_format())
            .finish()
    }
}

/// What the rasterizer draws into: a [`Surface`], or a [`crate::Framebuffer`], which lends one
/// over its own buffers.
pub trait AsSurface {
    /// The picture as a surface, borrowed for one draw or batch.
    fn as_surface(&mut self) -> Surface<'_>;
}

impl AsSurface for Surface<'_> {
    fn as_surface(&mut self) -> Surface<'_> {
        Surface {
            width: self.width,
            height: self.height,
            color: match &mut self.color {
                ColorMut::Rgb565(r) => ColorMut::Rgb565(r.reborrow()),
                ColorMut::Bgr565(r) => ColorMut::Bgr565(r.reborrow()),
                ColorMut::Xrgb8888(r) => ColorMut::Xrgb8888(r.reborrow()),
                ColorMut::Xbgr8888(r) => ColorMut::Xbgr8888(r.reborrow()),
                ColorMut::Rgba8888(r) => ColorMut::Rgba8888(r.reborrow()),
            },
            depth: match &mut self.depth {
                DepthMut::None => DepthMut::None,
                DepthMut::D16(d) => DepthMut::D16(d),
                DepthMut::D32(d) => DepthMut::D32(d),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn refusal(len: usize, offset: usize, stride: usize, layout: PixelLayout) -> SurfaceError {
        let mut memory = vec![0u32; len.div_ceil(4) + 1];
        let bytes: &mut [u8] = bytemuck::cast_slice_mut(&mut memory);
        match Surface::new(&mut bytes[offset..offset + len], 4, 3, stride, layout) {
            Err(RasterError::Surface(e)) => e,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn bad_memory_is_refused_with_the_reason() {
        use PixelLayout::*;
        assert_eq!(
            refusal(100, 0, 15, Xrgb8888),
            SurfaceError::StrideTooSmall {
                stride: 15,
                row: 16
            }
        );
        assert_eq!(
            refusal(100, 0, 18, Xrgb8888),
            SurfaceError::StrideNotWhole {
                stride: 18,
                pixel: 4
            }
        );
        assert_eq!(
            refusal(2 * 20 + 15, 0, 20, Rgba8888),
            SurfaceError::TooShort {
                needed: 56,
                got: 55
            }
        );
        assert!(matches!(
            refusal(100, 2, 16, Xbgr8888),
            SurfaceError::Misaligned { align: 4, .. }
        ));
        assert!(matches!(
            refusal(100, 1, 8, Bgr565),
            SurfaceError::Misaligned { align: 2, .. }
        ));
        let mut bytes = [0u8; 8];
        assert_eq!(
            Surface::new(&mut bytes, 0, 1, 8, Rgba8888).unwrap_err(),
            RasterError::FramebufferSize {
                width: 0,
                height: 1
            }
        );
        let mut memory = [0u16; 12];
        let mut depth = DepthBuffer::new(4, 2, DepthFormat::D32);
        let err = Surface::new(bytemuck::cast_slice_mut(&mut memory), 4, 3, 8, Rgb565)
            .unwrap()
            .with_depth(&mut depth)
            .unwrap_err();
        assert_eq!(
            err.to_string(),
            "surface refused: depth buffer holds 8 values, expected 12 (one per pixel)"
        );
    }

    #[test]
    fn rgba_bytes_need_no_alignment_and_clearing_leaves_the_padding() {
        let mut memory = [7u8; 3 * 12 + 1];
        let mut s = Surface::new(&mut memory[1..], 2, 3, 12, PixelLayout::Rgba8888).unwrap();
        s.clear([1, 2, 3]);
        assert_eq!(s.pixel(1, 2), [1, 2, 3]);
        assert_eq!(memory[1..9], [1, 2, 3, 255, 1, 2, 3, 255]);
        assert_eq!(memory[9..13], [7; 4]);
        assert_eq!(memory[0], 7);
    }

    #[test]
    fn clearing_565_rows_fills_every_row_and_leaves_the_padding() {
        // 3 pixels of 2 bytes to a row, rows 8 bytes apart: 2 bytes of padding after each.
        let mut memory = [7u8; 8 * 3];
        let mut s = Surface::new(&mut memory, 3, 3, 8, PixelLayout::Rgb565).unwrap();
        s.clear([255, 0, 255]);
        for y in 0..3 {
            for x in 0..3 {
                assert_eq!(s.pixel(x, y), [255, 0, 255], "({x}, {y})");
            }
        }
        for row in memory.chunks(8) {
            assert_eq!(row[..6], [0x1f, 0xf8, 0x1f, 0xf8, 0x1f, 0xf8]);
            assert_eq!(row[6..], [7; 2]);
        }
    }
}
