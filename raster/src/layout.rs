//! The pixel layouts a [`crate::Surface`] can hold, with the Linux DRM fourcc meanings, and how
//! each converts to the format its tiles are drawn in.
//!
//! Tiles are drawn in one of the two formats the inner loops are compiled for: 5-6-5 words for
//! the 16-bit layouts, R, G, B, A bytes for the 32-bit ones. A layout of another channel order
//! is converted when a tile is copied out of the surface and back, a bijection, so pixels no
//! triangle covers go back unchanged and a drawn pixel gets exactly the drawn colour.

/// How a surface stores a pixel. Words (16 or 32 bits) are in the machine's byte order, as the
/// Linux framebuffer and DRM dumb buffers store them; the byte orders named below are those of
/// a little-endian machine.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PixelLayout {
    /// 16-bit word, red in bits 15-11, green 10-5, blue 4-0 (DRM `RG16`).
    Rgb565,
    /// 16-bit word, blue in bits 15-11, green 10-5, red 4-0 (DRM `BG16`).
    Bgr565,
    /// 32-bit word `0xXXRRGGBB`: bytes B, G, R, X (DRM `XR24`). X is written as 0xFF.
    Xrgb8888,
    /// 32-bit word `0xXXBBGGRR`: bytes R, G, B, X (DRM `XB24`). X is written as 0xFF.
    Xbgr8888,
    /// Bytes R, G, B, A whatever the byte order (DRM `AB24` on a little-endian machine), A
    /// written as 0xFF: [`crate::ColorFormat::Rgba8888`]'s layout.
    Rgba8888,
}

impl PixelLayout {
    /// Every layout.
    pub const ALL: [Self; 5] = [
        Self::Rgb565,
        Self::Bgr565,
        Self::Xrgb8888,
        Self::Xbgr8888,
        Self::Rgba8888,
    ];

    /// Bytes a pixel takes; rows of a surface start at multiples of it.
    pub fn bytes_per_pixel(self) -> usize {
        match self {
            Self::Rgb565 | Self::Bgr565 => 2,
            Self::Xrgb8888 | Self::Xbgr8888 | Self::Rgba8888 => 4,
        }
    }

    /// The alignment a surface's memory needs: that of the layout's word (1 for bytes).
    pub fn alignment(self) -> usize {
        match self {
            Self::Rgb565 | Self::Bgr565 => align_of::<u16>(),
            Self::Xrgb8888 | Self::Xbgr8888 => align_of::<u32>(),
            Self::Rgba8888 => 1,
        }
    }
}

/// Swaps the 5-bit fields at the ends of a 5-6-5 word: RGB565 to BGR565 and back.
#[inline]
pub(crate) fn swap_565(p: u16) -> u16 {
    (p << 11) | (p & 0x07E0) | (p >> 11)
}

/// An XRGB8888 word as R, G, B, A bytes (A is X).
#[inline]
pub(crate) fn xrgb_to_rgba(w: u32) -> [u8; 4] {
    let [b, g, r, x] = w.to_le_bytes();
    [r, g, b, x]
}

/// R, G, B, A bytes as an XRGB8888 word (X is A).
#[inline]
pub(crate) fn rgba_to_xrgb([r, g, b, a]: [u8; 4]) -> u32 {
    u32::from_le_bytes([b, g, r, a])
}

/// An XBGR8888 word as R, G, B, A bytes (A is X).
#[inline]
pub(crate) fn xbgr_to_rgba(w: u32) -> [u8; 4] {
    w.to_le_bytes()
}

/// R, G, B, A bytes as an XBGR8888 word (X is A).
#[inline]
pub(crate) fn rgba_to_xbgr(p: [u8; 4]) -> u32 {
    u32::from_le_bytes(p)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conversions_are_bijections_that_put_channels_where_drm_says() {
        for p in [0u16, 0xFFFF, 0xF800, 0x07E0, 0x001F, 0x1234] {
            assert_eq!(swap_565(swap_565(p)), p);
        }
        assert_eq!(swap_565(0xF800), 0x001F);
        let rgba = [0x12, 0x34, 0x56, 0xFF];
        assert_eq!(rgba_to_xrgb(rgba), 0xFF12_3456);
        assert_eq!(rgba_to_xbgr(rgba), 0xFF56_3412);
        assert_eq!(xrgb_to_rgba(rgba_to_xrgb(rgba)), rgba);
        assert_eq!(xbgr_to_rgba(rgba_to_xbgr(rgba)), rgba);
        for w in [0u32, 0x0102_0304, 0xFFFF_FFFF, 0x8000_0001] {
            assert_eq!(rgba_to_xrgb(xrgb_to_rgba(w)), w);
            assert_eq!(rgba_to_xbgr(xbgr_to_rgba(w)), w);
        }
    }
}
