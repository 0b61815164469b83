//! The divisions of the row loops: perspective quotients by one reciprocal, span lengths by a
//! table, and plane accumulators advanced by a product.

use crate::fixed_point::{TEXCOORD_LIMIT, saturate_i64};
#[cfg(any(test, not(target_pointer_width = "64")))]
use crate::fixed_point::{corrected_quotient, reciprocal_by_table, reciprocal_estimate};

/// `2^63 / q` rounded down, for `q >= 1`: the perspective quotients' reciprocal. One division
/// where the CPU divides 64-bit integers; a 32-bit core has no such instruction (its library
/// call takes hundreds), so there it is `quotient_by_table`, the same integer.
#[inline(always)]
fn reciprocal_63(q: u64) -> u64 {
    debug_assert!(q >= 1);
    #[cfg(target_pointer_width = "64")]
    let r = (1u64 << 63) / q;
    #[cfg(not(target_pointer_width = "64"))]
    let r = quotient_by_table(q);
    r
}

/// `reciprocal_63` in 32x32-bit products: the reciprocal of `q`'s top 31 bits from the seed
/// table and Newton steps (`reciprocal_by_table`), scaled, and corrected by the remainder until
/// it lies in `0..q`, so the result is the rounded-down quotient whatever the estimate was.
#[cfg(any(test, not(target_pointer_width = "64")))]
fn quotient_by_table(q: u64) -> u64 {
    const TOP: u64 = 1 << 63;
    let bits = 64 - q.leading_zeros();
    if q > 1 << 61 {
        // A quotient of at most 3.
        let (mut rest, mut quotient) = (TOP, 0);
        while rest >= q {
            rest -= q;
            quotient += 1;
        }
        quotient
    } else if bits > 31 {
        // q = n 2^k with n in [2^30, 2^31): the quotient is 2^62 / n scaled by 2^(1 - k), within
        // a few units, below 2^33; the correction below makes it exact, so 2^62 / n need not be.
        let k = bits - 31;
        let estimate = reciprocal_estimate((q >> k) as u32) >> (k - 1);
        corrected_quotient(estimate, TOP, q)
    } else {
        // q = m / 2^s with m in [2^30, 2^31): 2^63 / q = R 2^(1+s) + (2^62 - m R) 2^(1+s) / m
        // for R = 2^62 / m rounded down, the second quotient below 2^(1+s) and estimated by R.
        let s = 31 - bits;
        let m = q << s;
        let r = reciprocal_by_table(m as u32) as u64;
        let rest = (1u64 << 62) - m * r;
        let low = corrected_quotient((rest * r) >> (61 - s), rest << (1 + s), m);
        (r << (1 + s)) + low
    }
}

/// `(u, v)` in 16.32 at a point from the perspective accumulators: one division per call.
/// Clamped to the texture-coordinate range, which extrapolation past a span end can leave.
#[inline]
pub(crate) fn divide(s: i64, t: i64, q: i64) -> (i64, i64) {
    let r = reciprocal_63(q.max(1) as u64) as i128;
    #[cfg(target_pointer_width = "64")]
    let uv = |a: i64| ((a as i128 * r) >> 47).clamp(-UV_LIMIT as i128, UV_LIMIT as i128) as i64;
    #[cfg(not(target_pointer_width = "64"))]
    let uv = |a: i64| clamped_in_words(a as i128 * r);
    (uv(s), uv(t))
}

/// The limit of `divide`'s coordinates (16.32).
const UV_LIMIT: i64 = TEXCOORD_LIMIT << 16;

/// `(p >> 47).clamp(-UV_LIMIT, UV_LIMIT)`, `divide`'s clamp, for a 32-bit core, where a clamp
/// of 128-bit values is a few dozen instructions: the product's high word alone decides it.
/// With the limit at 2^40, `p >> 47` lies in `-2^40..2^40`, inside the limit, exactly when
/// `-2^87 <= p < 2^87`, when the high word lies in `-2^23..2^23`; past either end the clamp
/// gives that end's limit.
#[cfg(any(test, not(target_pointer_width = "64")))]
#[inline(always)]
fn clamped_in_words(p: i128) -> i64 {
    const _: () = assert!(UV_LIMIT == 1 << 40);
    let high = (p >> 64) as i64;
    if !(-(1 << 23)..1 << 23).contains(&high) {
        return if high < 0 { -UV_LIMIT } else { UV_LIMIT };
    }
    (p >> 47) as i64
}

/// `divide` where the quotients are known to be inside the range (`q >= 2` and
/// `|s|, |t| <= q * TEXCOORD_LIMIT`, so `|s| * 2^16 / q <= TEXCOORD_LIMIT << 16`): the same
/// values without the clamps, each a 64x64-bit product and a shift (`q >= 2` keeps the
/// reciprocal below 2^63, in i64).
#[inline(always)]
pub(crate) fn divide_in_range(s: i64, t: i64, q: i64) -> (i64, i64) {
    debug_assert!(
        q >= 2
            && s.unsigned_abs().max(t.unsigned_abs()) as u128 <= q as u128 * TEXCOORD_LIMIT as u128
    );
    let r = reciprocal_63(q as u64) as i64;
    let uv = |a: i64| ((a as i128 * r as i128) >> 47) as i64;
    let out = (uv(s), uv(t));
    debug_assert_eq!(out, divide(s, t, q));
    out
}

/// `2^32 / n` for span lengths `n` in `1..=64`, rounded up.
const RECIPROCALS: [i64; 65] = {
    let mut t = [0i64; 65];
    let mut n = 1;
    while n <= 64 {
        t[n] = ((1i64 << 32) + n as i64 - 1) / n as i64;
        n += 1;
    }
    t
};

/// `d / n` for a span length `n <= 64` by a multiplication: a division per span would cost more
/// than the span's pixels. Exact for the `|d| < 2^41` of texture-coordinate differences.
#[inline]
pub(super) fn div_small(d: i64, n: i64) -> i64 {
    #[cfg(target_pointer_width = "64")]
    return ((d as i128 * RECIPROCALS[n as usize] as i128) >> 32) as i64;
    #[cfg(not(target_pointer_width = "64"))]
    return div_small_in_words(d, n);
}

/// `div_small`'s `(d * r) >> 32` for a 32-bit core, where a 128-bit product is a dozen
/// multiplications: with `d = high * 2^32 + low` (`low` unsigned), it is `high * r` plus the
/// high word of `low * r`, one product of words each (`r` is below 2^31 past `n = 2`; there
/// `r` is `2^32 / n` and the quotient `d >> (n - 1)`).
#[cfg(any(test, not(target_pointer_width = "64")))]
#[inline(always)]
fn div_small_in_words(d: i64, n: i64) -> i64 {
    if n <= 2 {
        return d >> (n - 1);
    }
    let r = RECIPROCALS[n as usize];
    debug_assert!(r < 1 << 31);
    let (high, low) = ((d >> 32) as i32 as i64, d as u32 as u64);
    high * r as i32 as i64 + ((low * r as u32 as u64) >> 32) as i64
}

/// A plane's accumulator `k` chunks of `step` after `start`, as repeated saturating additions
/// would leave it (the steps share one sign, so the sum saturates once and stays there).
#[inline]
pub(super) fn advance(start: i64, step: i64, k: i64) -> i64 {
    saturate_i64(start as i128 + step as i128 * k as i128)
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    #[test]
    fn the_table_quotient_is_the_division_at_every_magnitude() {
        for bits in 0..63 {
            for q in [
                1u64 << bits,
                (1 << bits) + 1,
                (2 << bits) - 1,
                3 << bits >> 1,
            ] {
                let q = q.max(1);
                assert_eq!(quotient_by_table(q), (1 << 63) / q, "{q}");
            }
        }
        for q in [
            (1 << 63) - 1,
            1 << 63,
            (1 << 62) + 1,
            (1 << 61) + 1,
            3,
            5,
            7,
        ] {
            assert_eq!(quotient_by_table(q), (1 << 63) / q, "{q}");
        }
    }

    /// `clamped_in_words` against the 128-bit clamp it stands for.
    fn check_clamp(p: i128) {
        let wide = (p >> 47).clamp(-UV_LIMIT as i128, UV_LIMIT as i128) as i64;
        assert_eq!(clamped_in_words(p), wide, "{p}");
    }

    #[test]
    fn clamps_in_words_at_their_edges_are_the_128_bit_clamps() {
        // Products around `2^87` and the limit each way, and the extremes of `divide`'s.
        let edges = [
            0i128,
            1 << 87,
            1 << 64,
            (UV_LIMIT as i128) << 47,
            i64::MAX as i128,
        ];
        for e in edges {
            for p in [e - 1, e, e + 1, -e - 1, -e, -e + 1] {
                check_clamp(p);
            }
        }
        check_clamp(i64::MIN as i128 * (1i128 << 63));
        check_clamp(i64::MAX as i128 * (1i128 << 63));
    }

    proptest! {
        #[test]
        fn the_quotient_in_words_is_the_wide_product(d in any::<i64>(), n in 1i64..=64) {
            let wide = ((d as i128 * RECIPROCALS[n as usize] as i128) >> 32) as i64;
            prop_assert_eq!(div_small_in_words(d, n), wide);
        }

        #[test]
        fn clamps_in_words_are_the_128_bit_clamps(
            a in proptest::num::i64::ANY,
            q in prop_oneof![1u64..1 << 20, 1u64..=1 << 63],
            bits in 0u32..64,
        ) {
            let r = ((1u64 << 63) / q) as i128;
            check_clamp(a as i128 * r);
            check_clamp((a >> bits) as i128 * r);
        }

        #[test]
        fn any_divisor_has_the_divisions_quotient(q in 1u64..=1 << 63, shift in 0u32..63) {
            let q = (q >> shift).max(1);
            prop_assert_eq!(quotient_by_table(q), (1 << 63) / q);
        }
    }
}
