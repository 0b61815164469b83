//! Packing 8-bit RGB into the screen's pixel format, derived once from its bitfields.

use stripmask_raster::PixelLayout as Drawable;

use super::ScreenInfo;

/// A validated pixel format: how many bytes a pixel takes and where each channel goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct PixelLayout {
    bytes: usize,
    /// (shift right of the 8-bit value, shift left into place) per channel.
    channels: [(u32, u32); 3],
    /// Bits always set: the alpha channel, opaque.
    opaque: u32,
}

impl PixelLayout {
    /// The layout of `info`, or why it cannot be written.
    pub fn new(info: &ScreenInfo) -> Result<Self, String> {
        let bpp = info.bits_per_pixel;
        if !matches!(bpp, 16 | 24 | 32) {
            return Err(format!("{bpp} bits per pixel (supported: 16, 24 and 32)"));
        }
        let mut used = 0u32;
        let mut channels = [(0, 0); 3];
        for (k, (name, f)) in [
            ("red", info.red),
            ("green", info.green),
            ("blue", info.blue),
        ]
        .into_iter()
        .enumerate()
        {
            if !(1..=8).contains(&f.length) || f.offset + f.length > bpp {
                return Err(format!(
                    "{name} channel of {} bits at bit {} in a {bpp}-bit pixel (supported: 1 to 8 bits inside the pixel)",
                    f.length, f.offset
                ));
            }
            let mask = mask(f.offset, f.length);
            if used & mask != 0 {
                return Err(format!("{name} channel overlaps another channel"));
            }
            used |= mask;
            channels[k] = (8 - f.length, f.offset);
        }
        let t = info.transp;
        let opaque = if t.length == 0 {
            0
        } else if t.offset + t.length <= bpp && used & mask(t.offset, t.length) == 0 {
            mask(t.offset, t.length)
        } else {
            return Err(format!(
                "alpha channel of {} bits at bit {} overlaps a colour or leaves the {bpp}-bit pixel",
                t.length, t.offset
            ));
        };
        if info.width == 0 || info.height == 0 {
            return Err(format!("visible area of {}x{}", info.width, info.height));
        }
        let row_bytes = (u64::from(info.xoffset) + u64::from(info.width)) * u64::from(bpp / 8);
        if u64::from(info.line_length) < row_bytes {
            return Err(format!(
                "line length of {} bytes is shorter than {} pixels at column {}",
                info.line_length, info.width, info.xoffset
            ));
        }
        Ok(Self {
            bytes: (bpp / 8) as usize,
            channels,
            opaque,
        })
    }

    /// Bytes per pixel.
    pub fn bytes(&self) -> usize {
        self.bytes
    }

    /// The rasterizer's layout of the same bytes, when there is one: then frames are drawn
    /// straight into screen memory. Its X byte is written as 0xFF, so a 32-bit format qualifies
    /// only without alpha or with 8 bits of it at the top.
    pub fn drawable(&self) -> Option<Drawable> {
        match (self.bytes, self.channels, self.opaque) {
            (2, [(3, 11), (2, 5), (3, 0)], 0) => Some(Drawable::Rgb565),
            (2, [(3, 0), (2, 5), (3, 11)], 0) => Some(Drawable::Bgr565),
            (4, [(0, 16), (0, 8), (0, 0)], 0 | 0xFF00_0000) => Some(Drawable::Xrgb8888),
            (4, [(0, 0), (0, 8), (0, 16)], 0 | 0xFF00_0000) => Some(Drawable::Xbgr8888),
            _ => None,
        }
    }

    /// Writes `c` as one pixel into `out` (`bytes()` long), in the machine's byte order.
    #[inline]
    pub fn write(&self, c: [u8; 3], out: &mut [u8]) {
        let mut v = self.opaque;
        for (&value, &(drop, shift)) in c.iter().zip(&self.channels) {
            v |= (u32::from(value) >> drop) << shift;
        }
        match self.bytes {
            2 => out.copy_from_slice(&(v as u16).to_ne_bytes()),
            4 => out.copy_from_slice(&v.to_ne_bytes()),
            _ if cfg!(target_endian = "little") => out.copy_from_slice(&v.to_le_bytes()[..3]),
            _ => out.copy_from_slice(&v.to_be_bytes()[1..]),
        }
    }
}

/// `length` set bits from bit `offset`.
fn mask(offset: u32, length: u32) -> u32 {
    (((1u64 << length) - 1) << offset) as u32
}

#[cfg(test)]
mod tests {
    use super::super::Bitfield;
    use super::*;

    fn info(bpp: u32, rgb: [(u32, u32); 3], transp: (u32, u32)) -> ScreenInfo {
        ScreenInfo {
            width: 2,
            height: 2,
            bits_per_pixel: bpp,
            line_length: 2 * bpp / 8,
            red: Bitfield::new(rgb[0].0, rgb[0].1),
            green: Bitfield::new(rgb[1].0, rgb[1].1),
            blue: Bitfield::new(rgb[2].0, rgb[2].1),
            transp: Bitfield::new(transp.0, transp.1),
            ..ScreenInfo::default()
        }
    }

    #[test]
    fn formats_outside_what_can_be_written_are_refused_with_the_reason() {
        let bad = [
            (
                info(8, [(5, 3), (2, 3), (0, 2)], (0, 0)),
                "8 bits per pixel",
            ),
            (info(16, [(11, 5), (5, 6), (4, 5)], (0, 0)), "overlaps"),
            (
                info(32, [(16, 10), (8, 8), (0, 8)], (0, 0)),
                "red channel of 10 bits",
            ),
            (
                info(16, [(11, 5), (5, 6), (0, 0)], (0, 0)),
                "blue channel of 0 bits",
            ),
            (
                info(32, [(16, 8), (8, 8), (0, 8)], (20, 8)),
                "alpha channel",
            ),
        ];
        for (info, why) in bad {
            let err = PixelLayout::new(&info).unwrap_err();
            assert!(err.contains(why), "{err}");
        }
        let mut short = info(16, [(11, 5), (5, 6), (0, 5)], (0, 0));
        short.line_length = 3;
        assert!(
            PixelLayout::new(&short)
                .unwrap_err()
                .contains("line length")
        );
    }

    #[test]
    fn channels_land_at_their_offsets_with_alpha_opaque() {
        let argb = PixelLayout::new(&info(32, [(16, 8), (8, 8), (0, 8)], (24, 8))).unwrap();
        let mut out = [0u8; 4];
        argb.write([0x12, 0x34, 0x56], &mut out);
        assert_eq!(u32::from_ne_bytes(out), 0xFF12_3456);
        let bgr565 = PixelLayout::new(&info(16, [(0, 5), (5, 6), (11, 5)], (0, 0))).unwrap();
        let mut out = [0u8; 2];
        bgr565.write([0xFF, 0x00, 0x80], &mut out);
        assert_eq!(u16::from_ne_bytes(out), (0x10 << 11) | 0x1F);
    }

    #[test]
    fn the_rasterizers_layouts_are_recognised_and_others_are_not() {
        let rgb = [(16, 8), (8, 8), (0, 8)];
        let bgr = [(0, 8), (8, 8), (16, 8)];
        let drawable = |bpp, channels, transp| {
            PixelLayout::new(&info(bpp, channels, transp))
                .unwrap()
                .drawable()
        };
        assert_eq!(drawable(32, rgb, (0, 0)), Some(Drawable::Xrgb8888));
        assert_eq!(drawable(32, rgb, (24, 8)), Some(Drawable::Xrgb8888));
        assert_eq!(drawable(32, bgr, (0, 0)), Some(Drawable::Xbgr8888));
        assert_eq!(
            drawable(16, [(11, 5), (5, 6), (0, 5)], (0, 0)),
            Some(Drawable::Rgb565)
        );
        assert_eq!(
            drawable(16, [(0, 5), (5, 6), (11, 5)], (0, 0)),
            Some(Drawable::Bgr565)
        );
        assert_eq!(drawable(32, rgb, (24, 4)), None);
        assert_eq!(drawable(24, rgb, (0, 0)), None);
        assert_eq!(drawable(16, [(10, 5), (5, 5), (0, 5)], (15, 1)), None);
    }
}
