//! Named fixed-point formats of the pipeline and the bounds every stage relies on.
//!
//! Every integer width in the rasterizer follows from the constants here; the comments give the
//! arithmetic that proves an overflow impossible, so a change to one constant shows what else moves.

use fixed::types::I16F16;

/// Texture coordinate, 16.16: `1.0` spans the texture once.
pub type TexCoord = I16F16;

/// Fractional bits of the sub-pixel grid (1/256 pixel): screen positions are 24.8 integers.
pub const SUBPIXEL_BITS: u32 = 8;
/// One pixel in sub-pixel units.
pub const SUBPIXEL_ONE: i64 = 1 << SUBPIXEL_BITS;
/// Half a pixel in sub-pixel units: pixel centres sit at `px * ONE + HALF`.
pub const SUBPIXEL_HALF: i64 = SUBPIXEL_ONE / 2;

/// Largest framebuffer side in pixels.
pub const MAX_DIMENSION: u32 = 8192;

/// Guard band: a vertex is drawn without side clipping while it projects within this many pixels of
/// the viewport centre. Screen coordinates then lie in `[-2^15, 2^16]` px, that is `|x| < 2^24`
/// sub-pixels; edge deltas stay below `2^25`, edge-function products below `2^50`: i64 has room to
/// spare. Triangles beyond it are clipped against the band in homogeneous space instead.
pub const GUARD_BAND_PX: i64 = 1 << 15;

/// Largest magnitude of a texture coordinate the pipeline interpolates (256 repeats). Coordinates
/// beyond it are clamped at the vertex, so `u * q` (q below `2^Q_BITS`) stays below `2^44`, and below `2^60` with the
/// interpolation bits.
pub const TEXCOORD_LIMIT: i64 = 256 << 16;

/// Fractional bits of the normalised reciprocal `q = 1/w` used for perspective correction.
pub const Q_BITS: u32 = 20;

/// Depth values are unsigned 0.32: `0` at the near plane, `DEPTH_ONE` at the far plane.
pub const DEPTH_ONE: i64 = 1 << 32;

/// Extra fractional bits carried by interpolated attributes so that stepping across a span does not
/// accumulate rounding error.
pub const ATTR_FRAC_BITS: u32 = 16;

/// `ceil(n / d)` for `d > 0`, exact for any sign of `n`.
#[inline]
pub fn ceil_div(n: i64, d: i64) -> i64 {
    debug_assert!(d > 0);
    -((-n).div_euclid(d))
}

/// `floor(n / d)` for `d > 0`, exact for any sign of `n`.
#[inline]
pub fn floor_div(n: i64, d: i64) -> i64 {
    debug_assert!(d > 0);
    n.div_euclid(d)
}

/// Shift that brings a positive `v` into `[2^30, 2^31)`, as `(v normalised, shift)` where
/// `v ≈ normalised * 2^shift`. Used to take reciprocals with one 64-bit division.
#[inline]
pub fn normalise_positive(v: i128) -> (i64, i32) {
    debug_assert!(v > 0);
    let bits = 128 - v.leading_zeros() as i32; // position of the top bit + 1
    let shift = bits - 31;
    let n = if shift >= 0 { v >> shift } else { v << -shift };
    (n as i64, shift)
}

/// Shift `v` right by `s` when `s > 0` and left by `-s` otherwise, rounding to nearest.
#[inline]
pub fn shift_round(v: i128, s: i32) -> i128 {
    if s > 0 {
        (v + (1i128 << (s - 1))) >> s
    } else {
        v << -s
    }
}

/// Saturates an i128 into the i64 range.
#[inline]
pub fn saturate_i64(v: i128) -> i64 {
    v.clamp(i64::MIN as i128, i64::MAX as i128) as i64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ceil_and_floor_division_round_toward_the_right_side_for_both_signs() {
        assert_eq!(ceil_div(7, 2), 4);
        assert_eq!(ceil_div(-7, 2), -3);
        assert_eq!(ceil_div(6, 2), 3);
        assert_eq!(floor_div(-7, 2), -4);
        assert_eq!(floor_div(7, 2), 3);
    }

    #[test]
    fn normalise_puts_the_top_bit_at_position_30() {
        for v in [1i128, 3, 1 << 30, (1 << 31) - 1, 1 << 62, i64::MAX as i128] {
            let (n, s) = normalise_positive(v);
            assert!((1 << 30..1 << 31).contains(&n), "{v} -> {n}");
            if s <= 0 {
                assert_eq!(n as i128, v << -s);
            } else {
                assert!((n as i128) << s <= v && v < ((n as i128 + 1) << s));
            }
        }
    }

    #[test]
    fn shift_round_rounds_half_up() {
        assert_eq!(shift_round(5, 1), 3);
        assert_eq!(shift_round(4, 1), 2);
        assert_eq!(shift_round(-5, 1), -2);
        assert_eq!(shift_round(3, -2), 12);
    }
}
