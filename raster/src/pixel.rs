//! Pixel and depth formats as types, so the inner loop is compiled once per format.

use crate::fixed_point::ATTR_FRAC_BITS;
use crate::lanes::{LANES, Rgb8s, u16x8, u32x8};

/// Packs 8-bit RGB into 5-6-5 (rounding to nearest).
#[inline]
pub fn rgb_to_rgb565(c: [u8; 3]) -> u16 {
    let r = (c[0] as u16 * 31 + 127) / 255;
    let g = (c[1] as u16 * 63 + 127) / 255;
    let b = (c[2] as u16 * 31 + 127) / 255;
    (r << 11) | (g << 5) | b
}

/// Expands 5-6-5 to 8-bit RGB by bit replication (exact at 0 and 255).
#[inline]
pub fn rgb565_to_rgb(p: u16) -> [u8; 3] {
    let r = ((p >> 11) & 31) as u8;
    let g = ((p >> 5) & 63) as u8;
    let b = (p & 31) as u8;
    [
        (r << 3) | (r >> 2),
        (g << 2) | (g >> 4),
        (b << 3) | (b >> 2),
    ]
}

/// A colour-buffer format.
pub trait PixelFormat: Send + Sync + 'static {
    /// Stored pixel.
    type Pixel: Copy + Send + Sync + 'static;
    /// Colour to stored pixel.
    fn pack(c: [u8; 3]) -> Self::Pixel;
    /// Stored pixel to colour.
    fn unpack(p: Self::Pixel) -> [u8; 3];
    /// `pack` of eight colours.
    fn pack_lanes(c: Rgb8s) -> [Self::Pixel; LANES];
}

/// 16-bit 5-6-5, the handheld's format.
pub struct Rgb565;
/// 32-bit, bytes R, G, B, A (alpha written as 255).
pub struct Rgba8888;

impl PixelFormat for Rgb565 {
    type Pixel = u16;
    #[inline]
    fn pack(c: [u8; 3]) -> u16 {
        // Truncation, not rounding, in the hot loop: one shift per channel.
        ((c[0] as u16 >> 3) << 11) | ((c[1] as u16 >> 2) << 5) | (c[2] as u16 >> 3)
    }
    #[inline]
    fn unpack(p: u16) -> [u8; 3] {
        rgb565_to_rgb(p)
    }
    #[inline(always)]
    fn pack_lanes(c: Rgb8s) -> [u16; LANES] {
        ((c.r >> 3u32) << 11u32 | (c.g >> 2u32) << 5u32 | c.b >> 3u32).to_array()
    }
}

impl PixelFormat for Rgba8888 {
    type Pixel = [u8; 4];
    #[inline]
    fn pack(c: [u8; 3]) -> [u8; 4] {
        [c[0], c[1], c[2], 255]
    }
    #[inline]
    fn unpack(p: [u8; 4]) -> [u8; 3] {
        [p[0], p[1], p[2]]
    }
    #[inline(always)]
    fn pack_lanes(c: Rgb8s) -> [[u8; 4]; LANES] {
        let wide = |c: u16x8| u32x8::from(c);
        let p = wide(c.r) | wide(c.g) << 8u32 | wide(c.b) << 16u32 | u32x8::splat(0xFF00_0000);
        p.to_array().map(u32::to_le_bytes)
    }
}

/// How a depth buffer stores depth, as a type (or that there is none), so that the inner loop
/// is compiled once per storage; [`crate::DepthFormat`] names the same choice at run time. Depth
/// arrives as unsigned 0.32.
pub trait DepthStorage: Send + Sync + 'static {
    /// Stored value.
    type Value: Copy + Ord + Send + Sync + 'static;
    /// False for the no-depth format: the test and the write compile away.
    const ENABLED: bool;
    /// Depth 0.32 to stored value (keeps the top bits).
    fn quantise(d: u32) -> Self::Value;
    /// An interpolated depth (0.32 with `ATTR_FRAC_BITS` more) clamped to 0.32 and quantised:
    /// `quantise((z >> ATTR_FRAC_BITS).clamp(0, u32::MAX))`.
    fn from_z(z: i64) -> Self::Value;
    /// `from_z` of a `z` known to lie in `0..2^48` (no clamp needed).
    fn from_z_in_range(z: i64) -> Self::Value;
    /// A stored value and a depth test's bias on one scale (`DepthTest`): on a 32-bit core a
    /// `u32` where it holds both (`Short`).
    type Wide: Copy + Ord + std::ops::Add<Output = Self::Wide>;
    /// A stored value as a `Wide`.
    fn widen(v: Self::Value) -> Self::Wide;
    /// A test's bias (0, 1 or at least 2^32, `DepthTest`) as a `Wide`: any bias above the
    /// largest stored value passes every value as 2^32 does.
    fn bias(b: u64) -> Self::Wide;
}

/// The depth test's scale for stored values below 2^16: a word on a 32-bit core, where the
/// test is then one comparison instead of a `u64` sum and comparison of two words; a 64-bit
/// core compares `u64` as cheaply, and the bias then needs no cap.
#[cfg(target_pointer_width = "64")]
pub type Short = u64;
/// See the other `Short`.
#[cfg(not(target_pointer_width = "64"))]
pub type Short = u32;

/// A test's bias on the scale `Short`: capped at 2^16 on a 32-bit core, which passes every
/// value below 2^16 as any larger bias does.
#[inline(always)]
fn short_bias(b: u64) -> Short {
    #[cfg(not(target_pointer_width = "64"))]
    let b = b.min(1 << 16) as u32;
    b
}

/// No depth buffer, or depth off.
pub struct NoDepth;
/// 16-bit depth.
pub struct Depth16;
/// 32-bit depth.
pub struct Depth32;

impl DepthStorage for NoDepth {
    type Value = u8;
    const ENABLED: bool = false;
    #[inline]
    fn quantise(_: u32) -> u8 {
        0
    }
    #[inline(always)]
    fn from_z(_: i64) -> u8 {
        0
    }
    #[inline(always)]
    fn from_z_in_range(_: i64) -> u8 {
        0
    }
    type Wide = Short;
    #[inline(always)]
    fn widen(v: u8) -> Short {
        v as Short
    }
    #[inline(always)]
    fn bias(b: u64) -> Short {
        short_bias(b)
    }
}

impl DepthStorage for Depth16 {
    type Value = u16;
    const ENABLED: bool = true;
    #[inline]
    fn quantise(d: u32) -> u16 {
        (d >> 16) as u16
    }
    /// The top 16 bits of the clamped 0.32 depth are the clamped top bits of `z`.
    #[inline(always)]
    fn from_z(z: i64) -> u16 {
        (z >> (16 + ATTR_FRAC_BITS)).clamp(0, u16::MAX as i64) as u16
    }
    #[inline(always)]
    fn from_z_in_range(z: i64) -> u16 {
        debug_assert!((0..1 << 48).contains(&z));
        (z >> (16 + ATTR_FRAC_BITS)) as u16
    }
    type Wide = Short;
    #[inline(always)]
    fn widen(v: u16) -> Short {
        v as Short
    }
    #[inline(always)]
    fn bias(b: u64) -> Short {
        short_bias(b)
    }
}

impl DepthStorage for Depth32 {
    type Value = u32;
    const ENABLED: bool = true;
    #[inline]
    fn quantise(d: u32) -> u32 {
        d
    }
    #[inline(always)]
    fn from_z(z: i64) -> u32 {
        (z >> ATTR_FRAC_BITS).clamp(0, u32::MAX as i64) as u32
    }
    #[inline(always)]
    fn from_z_in_range(z: i64) -> u32 {
        debug_assert!((0..1 << 48).contains(&z));
        (z >> ATTR_FRAC_BITS) as u32
    }
    type Wide = u64;
    #[inline(always)]
    fn widen(v: u32) -> u64 {
        v as u64
    }
    #[inline(always)]
    fn bias(b: u64) -> u64 {
        b
    }
}

/// Texture colour modulated by the shading colour: `t * (c + 1) / 256`, exact at 0 and 255.
#[inline]
pub fn modulate(t: [u8; 3], c: [u8; 3]) -> [u8; 3] {
    [0, 1, 2].map(|k| ((t[k] as u32 * (c[k] as u32 + 1)) >> 8) as u8)
}

/// Blend towards the fog colour: `f` is the share of the surface colour, 0..=256.
#[inline]
pub fn fog_blend(c: [u8; 3], fog: [u8; 3], f: u32) -> [u8; 3] {
    [0, 1, 2].map(|k| ((c[k] as u32 * f + fog[k] as u32 * (256 - f)) >> 8) as u8)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The depth test's one comparison on each storage's scale (`DepthStorage::Wide`) against
    /// the three tests it stands for, at the ends of each storage's values: less (bias 0),
    /// less-or-equal (1) and always (2^32, `DepthTest`).
    fn one_comparison_is_the_test<D: DepthStorage>(values: &[D::Value]) {
        for &d in values {
            for &s in values {
                let passes = |b: u64| D::widen(d) < D::widen(s) + D::bias(b);
                assert_eq!(
                    (passes(0), passes(1), passes(1 << 32)),
                    (d < s, d <= s, true)
                );
            }
        }
    }

    #[test]
    fn depth_tests_in_one_comparison_pass_what_their_comparisons_pass() {
        one_comparison_is_the_test::<NoDepth>(&[0]);
        one_comparison_is_the_test::<Depth16>(&[0, 1, 2, 0x7fff, 0xfffe, 0xffff]);
        one_comparison_is_the_test::<Depth32>(&[0, 1, 0xffff, 1 << 16, u32::MAX - 1, u32::MAX]);
    }

    #[test]
    fn rgb565_round_trips_its_own_values_and_keeps_black_and_white() {
        for p in [0u16, 0xFFFF, 0xF800, 0x07E0, 0x001F, 0x1234] {
            assert_eq!(rgb_to_rgb565(rgb565_to_rgb(p)), p);
            assert_eq!(Rgb565::pack(rgb565_to_rgb(p)), p);
        }
        assert_eq!(rgb565_to_rgb(0xFFFF), [255; 3]);
    }

    #[test]
    fn modulate_and_fog_are_exact_at_the_ends() {
        assert_eq!(modulate([255, 10, 0], [255, 255, 255]), [255, 10, 0]);
        assert_eq!(modulate([255, 10, 0], [0, 0, 0]), [0, 0, 0]);
        assert_eq!(fog_blend([10, 20, 30], [200, 200, 200], 256), [10, 20, 30]);
        assert_eq!(fog_blend([10, 20, 30], [200, 200, 200], 0), [200, 200, 200]);
    }

    #[test]
    fn depth_formats_keep_the_top_bits() {
        assert_eq!(Depth16::quantise(0xABCD_1234), 0xABCD);
        assert_eq!(Depth32::quantise(0xABCD_1234), 0xABCD_1234);
    }

    proptest::proptest! {
        #[test]
        fn depth_from_an_interpolated_value_clamps_then_quantises(z in proptest::num::i64::ANY, near in -(1i64 << 49)..1 << 49, inside in 0i64..1 << 48) {
            for z in [z, near, inside] {
                let d = (z >> ATTR_FRAC_BITS).clamp(0, u32::MAX as i64) as u32;
                proptest::prop_assert_eq!(Depth16::from_z(z), Depth16::quantise(d));
                proptest::prop_assert_eq!(Depth32::from_z(z), Depth32::quantise(d));
                if (0..1 << 48).contains(&z) {
                    proptest::prop_assert_eq!(Depth16::from_z_in_range(z), Depth16::from_z(z));
                    proptest::prop_assert_eq!(Depth32::from_z_in_range(z), Depth32::from_z(z));
                }
            }
        }
    }
}
