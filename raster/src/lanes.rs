//! Eight pixels at a time: the lane types of the colour stage and the conversions between them.
//!
//! The colour stage (texel addressing, the bilinear blend, modulation, fog, packing) works on 8
//! fragments at once in `wide`'s portable vectors (SSE2 or AVX2 on x86, NEON on aarch64, plain
//! arrays elsewhere). Channels live in 16-bit lanes: every product of the stage fits 16 bits
//! (an 8-bit channel times a weight of at most 256 is at most `255 * 256`), so one 16-bit
//! multiplication serves 8 fragments. Coordinates and texel addresses live in 32-bit lanes.

pub(crate) use wide::{i16x8, i32x8, u16x8, u32x8};

/// Fragments per group of lanes.
pub(crate) const LANES: usize = 8;

/// Whether `wide`'s lanes are vectors on the build target: SSE2, NEON on aarch64, WebAssembly
/// SIMD, as `wide` chooses (`cfg(wide_vectors)`, from `build.rs`). Elsewhere, 32-bit ARM
/// with or without NEON among them, `wide` keeps them as arrays worked element by element, a
/// group's channels outgrow the registers, and the colour stage runs one fragment at a time
/// instead (`fragments::one_by_one`), to the same bytes.
pub(crate) const VECTORS: bool = cfg!(wide_vectors);

/// Eight 8-bit colours, one vector per channel, each channel in `0..=255`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Rgb8s {
    pub r: u16x8,
    pub g: u16x8,
    pub b: u16x8,
}

impl Rgb8s {
    /// The same colour in every lane.
    #[inline(always)]
    pub fn splat(c: [u8; 3]) -> Self {
        Self {
            r: u16x8::splat(c[0] as u16),
            g: u16x8::splat(c[1] as u16),
            b: u16x8::splat(c[2] as u16),
        }
    }

    /// The same grey level `c` in all three channels.
    #[inline(always)]
    pub fn grey(c: u16x8) -> Self {
        Self { r: c, g: c, b: c }
    }

    /// The colour of lane `k`.
    #[cfg(test)]
    pub fn lane(&self, k: usize) -> [u8; 3] {
        [self.r, self.g, self.b].map(|c| c.to_array()[k] as u8)
    }
}

/// 32-bit lanes holding values in `0..=i16::MAX` as 16-bit lanes.
#[inline(always)]
pub(crate) fn narrow(v: i32x8) -> u16x8 {
    bytemuck::cast(i16x8::from_i32x8_saturate(v))
}

/// 32-bit lanes holding values in `0..=u16::MAX` as 16-bit lanes.
#[inline(always)]
pub(crate) fn narrow_u32(v: u32x8) -> u16x8 {
    bytemuck::cast(i16x8::from_i32x8_truncate(bytemuck::cast(v)))
}

/// Eight values starting at `s[at]` (the buffers are padded, so a group always has 8).
#[inline(always)]
pub(crate) fn load_u16(s: &[u16], at: usize) -> u16x8 {
    let a: [u16; LANES] = s[at..at + LANES].try_into().expect("8 lanes");
    u16x8::new(a)
}

/// Eight values starting at `s[at]`.
#[inline(always)]
pub(crate) fn load_i32(s: &[i32], at: usize) -> i32x8 {
    let a: [i32; LANES] = s[at..at + LANES].try_into().expect("8 lanes");
    i32x8::new(a)
}

/// Texture colour modulated by the shading colour: `t * (c + 1) / 256` per channel, as
/// [`crate::pixel::modulate`] (the products stay below `2^16`).
#[inline(always)]
pub(crate) fn modulate(t: Rgb8s, c: Rgb8s) -> Rgb8s {
    let m = |t: u16x8, c: u16x8| (t * (c + u16x8::splat(1))) >> 8;
    Rgb8s {
        r: m(t.r, c.r),
        g: m(t.g, c.g),
        b: m(t.b, c.b),
    }
}

/// Blend towards the fog colour, `f` the share of the surface colour in `0..=256`, as
/// [`crate::pixel::fog_blend`] (`c * f + fog * (256 - f) <= 255 * 256`).
#[inline(always)]
pub(crate) fn fog_blend(c: Rgb8s, fog: [u8; 3], f: u16x8) -> Rgb8s {
    let g = u16x8::splat(256) - f;
    let m = |c: u16x8, fog: u8| (c * f + u16x8::splat(fog as u16) * g) >> 8;
    Rgb8s {
        r: m(c.r, fog[0]),
        g: m(c.g, fog[1]),
        b: m(c.b, fog[2]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pixel;

    proptest::proptest! {
        #[test]
        fn modulation_and_fog_in_lanes_equal_the_scalar_functions(
            t in proptest::array::uniform8(proptest::array::uniform3(0u8..=255)),
            c in proptest::array::uniform8(proptest::array::uniform3(0u8..=255)),
            fog in proptest::array::uniform3(0u8..=255),
            f in proptest::array::uniform8(0u16..=256),
        ) {
            let lanes = |v: [[u8; 3]; 8]| Rgb8s {
                r: u16x8::new(v.map(|p| p[0] as u16)),
                g: u16x8::new(v.map(|p| p[1] as u16)),
                b: u16x8::new(v.map(|p| p[2] as u16)),
            };
            let m = modulate(lanes(t), lanes(c));
            let g = fog_blend(lanes(t), fog, u16x8::new(f));
            for k in 0..LANES {
                proptest::prop_assert_eq!(m.lane(k), pixel::modulate(t[k], c[k]));
                proptest::prop_assert_eq!(g.lane(k), pixel::fog_blend(t[k], fog, f[k] as u32));
            }
        }
    }

    #[test]
    fn narrowing_keeps_the_values() {
        let v = i32x8::new([0, 1, 255, 256, 32767, 7, 8, 9]);
        assert_eq!(narrow(v).to_array(), [0, 1, 255, 256, 32767, 7, 8, 9]);
        let w = u32x8::new([0, 65535, 255, 256, 32768, 7, 8, 9]);
        assert_eq!(
            narrow_u32(w).to_array(),
            [0, 65535, 255, 256, 32768, 7, 8, 9]
        );
    }
}
