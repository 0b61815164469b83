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
/// `v ≈ normalised * 2^shift`. Used to take reciprocals (`reciprocal`).
#[inline]
pub fn normalise_positive(v: i128) -> (i64, i32) {
    debug_assert!(v > 0);
    let bits = 128 - v.leading_zeros() as i32; // position of the top bit + 1
    let shift = bits - 31;
    let n = if shift >= 0 { v >> shift } else { v << -shift };
    (n as i64, shift)
}

/// `2^62 / n` rounded down, for a normalised `n` in `[2^30, 2^31)` (`normalise_positive`): the
/// reciprocal of `w` in the projection and of the area in set-up, in `(2^31, 2^32]`. One
/// division where the CPU divides 64-bit integers; a 32-bit core has no such instruction (its
/// library call takes hundreds), so there it is `reciprocal_by_table`, the same integer.
/// The engine's normals take their one quotient a sample from it too.
#[inline(always)]
pub fn reciprocal(n: i64) -> i64 {
    debug_assert!((1 << 30..1 << 31).contains(&n));
    #[cfg(target_pointer_width = "64")]
    let r = ((1u64 << 62) / n as u64) as i64;
    #[cfg(not(target_pointer_width = "64"))]
    let r = reciprocal_by_table(n as u32);
    r
}

/// Seeds of `reciprocal_by_table`: for `m` in `256..512`, `2^25 / (2m + 1)`, about
/// `2^40 / (m + 1/2)` shifted down by 16, the reciprocal of the middle of the `n` whose top 9
/// bits are `m`.
#[cfg(any(test, not(target_pointer_width = "64")))]
const RECIPROCAL_SEEDS: [u16; 256] = {
    let mut t = [0u16; 256];
    let mut i = 0;
    while i < 256 {
        t[i] = ((1u32 << 25) / (2 * (256 + i as u32) + 1)) as u16;
        i += 1;
    }
    t
};

/// `reciprocal` in 32x32-bit products, as the paper's era took reciprocals: a seed from a table
/// of 256 (within `2^-8.9` of `2^62 / n`), two Newton steps `x + x (2^62 - n x) / 2^62`
/// (each squares the relative error and truncates by at most 2: within `2^15`, then 3), and a
/// last step by the remainder `2^62 - n x`, taken until it lies in `0..n`: then `x` is the
/// rounded-down quotient itself, whatever the estimate was, so the result is exact by
/// construction (and tested against the division).
#[cfg(any(test, not(target_pointer_width = "64")))]
#[inline]
pub(crate) fn reciprocal_by_table(n: u32) -> i64 {
    // The remainder's true value is within a few `n` of 0.
    corrected_quotient(reciprocal_estimate(n), 1 << 62, n as u64) as i64
}

/// `reciprocal_by_table` before its last step: within a few units of `2^62 / n`, which is all
/// an estimate corrected by its own remainder later needs.
#[cfg(any(test, not(target_pointer_width = "64")))]
#[inline(always)]
pub(crate) fn reciprocal_estimate(n: u32) -> u64 {
    debug_assert!((1 << 30..1 << 31).contains(&n));
    let n64 = n as u64;
    let mut x = (RECIPROCAL_SEEDS[(n >> 22) as usize - 256] as u64) << 16;
    for _ in 0..2 {
        // `|e| < 2^62 / 2^8`: `e >> 30` fits in 32 bits, the product in 64.
        let e = (1i64 << 62).wrapping_sub((n64 * x) as i64);
        x = x.wrapping_add((((e >> 30) as i32 as i64 * x as i64) >> 32) as u64);
    }
    x
}

/// `estimate` of `numerator / divisor` (rounded down) corrected by the remainder until it lies
/// in `0..divisor`: exact whatever the estimate, as long as the estimate's remainder lies within
/// 2^63 of 0 (it is computed in wrapping arithmetic) and `divisor < 2^63`.
#[cfg(any(test, not(target_pointer_width = "64")))]
#[inline]
pub(crate) fn corrected_quotient(mut estimate: u64, numerator: u64, divisor: u64) -> u64 {
    let mut rest = numerator.wrapping_sub(estimate.wrapping_mul(divisor)) as i64;
    while rest < 0 {
        estimate -= 1;
        rest += divisor as i64;
    }
    while rest >= divisor as i64 {
        estimate += 1;
        rest -= divisor as i64;
    }
    estimate
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

    /// The seed and Newton steps against the division: at the ends of the range, around
    /// every seed's boundary, and at a stride through the whole range.
    #[test]
    fn the_reciprocal_by_table_is_the_division() {
        let division = |n: u32| ((1u64 << 62) / n as u64) as i64;
        let check = |n: u32| assert_eq!(reciprocal_by_table(n), division(n), "{n}");
        for m in 256u32..=512 {
            let edge = m << 22;
            for d in [0u32, 1, 2, 3, 1 << 21, (1 << 22) - 1] {
                for n in [edge.wrapping_sub(d + 1), edge.wrapping_add(d)] {
                    if (1 << 30..1 << 31).contains(&n) {
                        check(n);
                    }
                }
            }
        }
        for n in ((1u32 << 30)..(1 << 31)).step_by(4099) {
            check(n);
        }
    }

    proptest::proptest! {
        #[test]
        fn random_reciprocals_by_table_are_the_division(n in (1u32 << 30)..1 << 31) {
            proptest::prop_assert_eq!(reciprocal_by_table(n), ((1u64 << 62) / n as u64) as i64);
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
