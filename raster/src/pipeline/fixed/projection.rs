//! The integer vertex stage's projection: one reciprocal of a normalised `w` per vertex, the
//! 1/256-pixel snap, depth and fog, in i64 where the bounds allow and 128 bits elsewhere.

use super::clip::FixedClip;
use crate::fixed_point::{
    DEPTH_ONE, MAX_DIMENSION, SUBPIXEL_HALF, TEXCOORD_LIMIT, normalise_positive, reciprocal,
    saturate_i64, shift_round,
};
use crate::pipeline::{Attributes, TexMode, Viewport};

/// A projected vertex: snapped position and everything triangle setup needs.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct FixedScreen {
    /// Sub-pixel position.
    pub xy: [i64; 2],
    /// Depth, 0.32.
    pub(super) depth: i64,
    /// `1/w ≈ inv_w * 2^-(62 + w_shift)`.
    pub(super) inv_w: i64,
    pub(super) w_shift: i32,
    pub(super) uv: [i64; 2],
    pub(super) color: [i64; 3],
    /// The three colour channels are equal: worked out once per vertex, as the triangles that
    /// share it each ask (`FixedTriangle::grey`).
    pub(super) grey: bool,
    /// Share of the surface colour against fog, 0..=256.
    pub(super) fog: i64,
    /// Which of its attributes lie inside their ranges by a small triangle's margin
    /// (`Inner::of`).
    pub(super) inner: Inner,
}

impl FixedScreen {
    /// Depth, 0.32 (for the line path, which shares this projection).
    pub(crate) fn depth(&self) -> i64 {
        self.depth
    }
}

/// A vertex's attributes that lie inside the ranges their pixel values are clamped to by more
/// than a small triangle's planes can stray from the exact interpolation, one bit per kind:
/// a small triangle whose three vertices have the bits its planes need draws every pixel it owns
/// without the clamps (`FixedTriangle::bounded`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Inner(pub(super) u8);

impl Inner {
    pub(super) const DEPTH: u8 = 1;
    pub(super) const COLOR: u8 = 2;
    pub(super) const FOG: u8 = 4;
    pub(super) const UV: u8 = 8;

    /// Depth (0.32) this far inside `0..DEPTH_ONE`: a depth plane of a small triangle strays
    /// by less than `2^-31` of its vertices' spread (below `2^48` with the plane's 16 fraction
    /// bits, so below `2^17`) plus 18, and 3 units are `3 * 2^16`.
    pub(super) const DEPTH_MARGIN: i64 = 3;

    /// The bits of a vertex with these values: depth at least `DEPTH_MARGIN` inside its range,
    /// every colour channel and the fog share at least 1 (their ranges end at 255 and 256, a
    /// whole unit above the largest value a vertex holds), both texture coordinates above
    /// `-TEXCOORD_LIMIT` (the range ends one 16.16 unit above the largest, `TEXCOORD_LIMIT`).
    pub(super) fn of(depth: i64, color: [i64; 3], fog: i64, uv: [i64; 2]) -> Self {
        let bit = |inside: bool, b: u8| inside as u8 * b;
        Self(
            bit(
                (Self::DEPTH_MARGIN..DEPTH_ONE - Self::DEPTH_MARGIN).contains(&depth),
                Self::DEPTH,
            ) | bit(color.iter().all(|&c| c >= 1), Self::COLOR)
                | bit(fog >= 1, Self::FOG)
                | bit(uv.iter().all(|&c| c > -TEXCOORD_LIMIT), Self::UV),
        )
    }

    /// The bits a triangle's planes need: those of the attributes its draw interpolates, the
    /// texture coordinates when they are affine (perspective quotients are bounded per visit,
    /// `small::quotients_in_range`).
    pub(super) fn needed(a: &Attributes, tex: TexMode) -> Self {
        let bit = |used: bool, b: u8| used as u8 * b;
        Self(
            bit(a.depth, Self::DEPTH)
                | bit(a.shade, Self::COLOR)
                | bit(a.fog, Self::FOG)
                | bit(tex == TexMode::Affine, Self::UV),
        )
    }

    /// True when all three vertices have every bit of `needed`.
    pub(super) fn all(v: &[&FixedScreen; 3], needed: Self) -> bool {
        v[0].inner.0 & v[1].inner.0 & v[2].inner.0 & needed.0 == needed.0
    }
}

/// True when the channels of `color` are equal (terrain lighting: one plane serves all three).
pub(super) fn is_grey(color: [i64; 3]) -> bool {
    color[1] == color[0] && color[2] == color[0]
}

/// Fog distances on the clip `w` scale.
#[derive(Clone, Copy, Debug)]
pub(crate) struct FixedFog {
    pub start: i64,
    pub end: i64,
}

impl FixedFog {
    /// The share of the surface colour at clip `w` (`start < w < end` blends linearly):
    /// `((end - w) * 256 / (end - start))` clamped to `0..=256`, for `end > start`.
    ///
    /// Between the ends the quotient's 8 bits come from a restoring division, a bit at a time
    /// (the remainder stays below the divisor, below 2^63), where the 128-bit division is a
    /// library call of hundreds of instructions on a 32-bit core and dozens on a 64-bit one;
    /// beyond the ends the share is 0 or 256. Wider spans take the 128-bit division.
    #[inline]
    pub fn share(&self, w: i64) -> i64 {
        debug_assert!(self.end > self.start);
        let (d, x) = (
            self.end as i128 - self.start as i128,
            self.end as i128 - w as i128,
        );
        if x <= 0 {
            return 0;
        }
        if x >= d {
            return 256;
        }
        if d >= 1 << 63 {
            return (x * 256 / d) as i64;
        }
        // `0 < x < d < 2^63`: both are u64, and so is twice the remainder.
        let (d, mut r, mut q) = (d as u64, x as u64, 0);
        for _ in 0..8 {
            r <<= 1;
            let bit = r >= d;
            r -= if bit { d } else { 0 };
            q = q << 1 | bit as i64;
        }
        q
    }
}

impl FixedScreen {
    #[inline(always)]
    pub fn project(v: &FixedClip, vp: &Viewport, fog: Option<FixedFog>) -> Self {
        let w = v.clip[3].max(1);
        let (xy, depth, inv_w, shift) = project_narrow(v.clip, w, vp).unwrap_or_else(|| {
            let (xy, depth, inv_w, shift) = project_wide(v.clip, vp);
            (vp.clamp_to_guard_band(xy), depth, inv_w, shift)
        });
        let fog = match fog {
            Some(f) if f.end > f.start => f.share(w),
            Some(f) => {
                if w < f.end {
                    256
                } else {
                    0
                }
            }
            None => 256,
        };
        Self {
            xy,
            depth,
            inv_w,
            w_shift: shift,
            uv: v.uv,
            color: v.color,
            grey: is_grey(v.color),
            fog,
            inner: Inner::of(depth, v.color, fog, v.uv),
        }
    }
}

/// What the projection gives: the snapped position (inside the guard band), depth (0.32),
/// `1/w` and its shift (see `FixedScreen::inv_w`).
type Projected = ([i64; 2], i64, i64, i32);

/// The projection in i64 products and one widening multiplication per coordinate, for the
/// vertices where the bounds allow it (almost all: those within 8 viewport half-sizes of the
/// centre and inside the depth range); `None` for the others.
///
/// Bounds: `x' = x * 2^-shift` (rounded down when `shift > 0`, exact otherwise), as
/// `project_wide` scales it; `|x'| < 2^34` and a viewport side up to 2^13 keep
/// `x' * SUBPIXEL_HALF * side` below `2^34 * 2^7 * 2^13 = 2^54`, and that times `inv_w <= 2^32`
/// below 2^86 (one widening multiplication, rounded in i128 as `shift_round` does). Depth
/// needs `0 <= z <= w`, so `0 <= z' <= wn` and `z' * inv_w <= wn * 2^62 / wn = 2^62`: an i64
/// product whose rounding half cannot overflow. The result is `project_wide`'s to the bit
/// (tested at the extremes and at random).
#[inline]
fn project_narrow(clip: [i64; 4], w: i64, vp: &Viewport) -> Option<Projected> {
    debug_assert!(w > 0 && vp.width <= MAX_DIMENSION && vp.height <= MAX_DIMENSION);
    const LIMIT: u32 = 34;
    let [x, y, z, _] = clip;
    if z < 0 || z > w {
        return None;
    }
    // `normalise_positive` of `w` in i64: `wn` in `[2^30, 2^31)`, `shift` in `-30..=32`.
    let shift = 33 - w.leading_zeros() as i32;
    let (wn, x, y, z) = if shift >= 0 {
        (w >> shift, x >> shift, y >> shift, z >> shift)
    } else {
        let up = -shift as u32;
        if (x.unsigned_abs() | y.unsigned_abs()) >> (LIMIT - up) != 0 {
            return None;
        }
        (w << up, x << up, y << up, z << up)
    };
    if (x.unsigned_abs() | y.unsigned_abs()) >> LIMIT != 0 {
        return None;
    }
    let inv_w = reciprocal(wn); // (2^31, 2^32]
    let half_w = vp.width as i64 * SUBPIXEL_HALF;
    let half_h = vp.height as i64 * SUBPIXEL_HALF;
    let sx = half_w + scaled_by_reciprocal(x * half_w, inv_w);
    let sy = half_h - scaled_by_reciprocal(y * half_h, inv_w);
    let depth = ((z * inv_w + (1 << 29)) >> 30).min(DEPTH_ONE - 1);
    Some((vp.clamp_to_guard_band([sx, sy]), depth, inv_w, shift))
}

/// `(a * inv + 2^61) >> 62`, `project_narrow`'s rounded product, for `|a| < 2^54` and `inv` in
/// `(2^31, 2^32]`: one widening multiplication on a 64-bit core, `scaled_in_words` on a 32-bit
/// one, where the 128-bit product takes many.
#[inline(always)]
fn scaled_by_reciprocal(a: i64, inv: i64) -> i64 {
    debug_assert!(a.unsigned_abs() < 1 << 54 && (1 << 31) < inv && inv <= 1 << 32);
    #[cfg(target_pointer_width = "64")]
    let r = ((a as i128 * inv as i128 + (1 << 61)) >> 62) as i64;
    #[cfg(not(target_pointer_width = "64"))]
    let r = scaled_in_words(a, inv);
    r
}

/// `scaled_by_reciprocal` from products of `inv` by the two words of `a`: with
/// `a = 2^32 hi + lo` (`lo` unsigned), `a inv + 2^61 = 2^32 (hi inv + 2^29) + lo inv`, so the
/// sum shifted by 32 is `hi inv + 2^29 + (lo inv >> 32)` exactly (`|hi inv| < 2^54`,
/// `lo inv < 2^64`), and that shifted by 30 more is the result.
#[cfg(any(test, not(target_pointer_width = "64")))]
#[inline(always)]
fn scaled_in_words(a: i64, inv: i64) -> i64 {
    let (hi, lo) = ((a >> 32) as i32 as i64, a as u32 as u64);
    (hi * inv + (1 << 29) + ((lo * inv as u64) >> 32) as i64) >> 30
}

/// The projection of any clip position (`w` taken as at least 1) in 128-bit products: the
/// position before the guard band's clamp.
fn project_wide(clip: [i64; 4], vp: &Viewport) -> Projected {
    let [x, y, z, w] = clip.map(i128::from);
    let w = w.max(1);
    let (wn, shift) = normalise_positive(w);
    let scale = |c: i128| if shift > 0 { c >> shift } else { c << -shift };
    let inv_w = reciprocal(wn); // (2^31, 2^32]
    let half_w = vp.width as i128 * SUBPIXEL_HALF as i128;
    let half_h = vp.height as i128 * SUBPIXEL_HALF as i128;
    // Inside the guard band |x'| < 2^48, so the products stay below 2^100.
    let sx = half_w + shift_round(scale(x) * inv_w as i128 * half_w, 62);
    let sy = half_h - shift_round(scale(y) * inv_w as i128 * half_h, 62);
    let depth = shift_round(scale(z) * inv_w as i128, 30).clamp(0, DEPTH_ONE as i128 - 1) as i64;
    ([saturate_i64(sx), saturate_i64(sy)], depth, inv_w, shift)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixed_point::GUARD_BAND_PX;

    /// `scaled_in_words` against the 128-bit product.
    fn check_words(a: i64, inv: i64) {
        let wide = (a as i128 * inv as i128 + (1 << 61)) >> 62;
        assert_eq!(scaled_in_words(a, inv) as i128, wide, "{a} {inv}");
    }

    #[test]
    fn products_in_words_equal_128_bit_products_at_the_bounds() {
        let top = (1i64 << 54) - 1;
        for a in [0, 1, (1 << 32) - 1, 1 << 32, (1 << 32) + 1, 1 << 53, top] {
            for inv in [(1i64 << 31) + 1, 3 << 30, (1 << 32) - 1, 1 << 32] {
                check_words(a, inv);
                check_words(-a, inv);
            }
        }
    }

    proptest::proptest! {
        #[test]
        fn products_in_words_equal_128_bit_products(
            a in -(1i64 << 54) + 1..1 << 54,
            inv in (1i64 << 31) + 1..=1 << 32,
            bits in 0u32..54,
        ) {
            check_words(a, inv);
            check_words(a >> bits, inv);
        }
    }

    /// `FixedFog::share` against the 128-bit quotient it replaces.
    fn check_share(start: i64, end: i64, w: i64) {
        let fog = FixedFog { start, end };
        let quotient = (end as i128 - w as i128) * 256 / (end as i128 - start as i128);
        assert_eq!(
            fog.share(w) as i128,
            quotient.clamp(0, 256),
            "{start} {end} {w}"
        );
    }

    #[test]
    fn fog_shares_at_the_ends_and_the_extremes() {
        let spans = [
            (0, 1),
            (0, 255),
            (0, 256),
            (0, 257),
            (-5, 1 << 40),
            (1, i64::MAX),
        ];
        let extremes = [
            (i64::MIN, i64::MAX),
            (i64::MIN, -1),
            ((1 << 62) - 1, 1 << 62),
        ];
        for (start, end) in spans.into_iter().chain(extremes) {
            let near = |c: i64| [c.saturating_sub(1), c, c.saturating_add(1)];
            let middle = ((start as i128 + end as i128) / 2) as i64;
            for w in [
                near(start),
                near(end),
                near(middle),
                near(1),
                near(i64::MAX),
            ]
            .concat()
            {
                check_share(start, end, w);
            }
        }
    }

    proptest::proptest! {
        #[test]
        fn fog_shares_equal_the_128_bit_quotient(
            start in proptest::num::i64::ANY,
            span in 1i64..1 << 40,
            wide in 1u64..=u64::MAX,
            at in 0.0f64..1.0,
        ) {
            // Spans of every size, and clip w within and around each.
            for span in [span as i128, wide as i128] {
                let end = (start as i128 + span).min(i64::MAX as i128) as i64;
                if end > start {
                    let w = start as i128 + ((end as i128 - start as i128) as f64 * at) as i128;
                    for w in [w - 1, w, w + 1] {
                        check_share(start, end, w.clamp(1, i64::MAX as i128) as i64);
                    }
                }
            }
        }
    }

    /// `project_narrow`, where it applies, against `project_wide`.
    fn check_projection(clip: [i64; 4], vp: &Viewport) -> bool {
        let w = clip[3].max(1);
        let Some(narrow) = project_narrow(clip, w, vp) else {
            return false;
        };
        let (xy, depth, inv_w, shift) = project_wide(clip, vp);
        assert_eq!(
            narrow,
            (vp.clamp_to_guard_band(xy), depth, inv_w, shift),
            "{clip:?} {vp:?}"
        );
        true
    }

    #[test]
    fn narrow_projection_equals_128_bit_products_at_the_extremes() {
        let ws = [
            1i64,
            (1 << 30) - 1,
            1 << 30,
            (1 << 31) - 1,
            1 << 31,
            (1 << 31) + 1,
            1 << 47,
            (1 << 61) + 12345,
            (1 << 62) - 1,
        ];
        let (mut narrow, mut all) = (0, 0);
        for size in [1u32, 320, MAX_DIMENSION] {
            let vp = Viewport {
                width: size,
                height: (size / 2).max(1),
            };
            for &w in &ws {
                let shift = 33 - w.leading_zeros() as i32;
                // The largest x the narrow path takes, one past it, the guard band's edge, and
                // the ends of i64.
                let edge = if shift >= 0 {
                    ((1i128 << 34) << shift) - 1
                } else {
                    ((1i128 << 34) >> -shift) - 1
                };
                let band = w as i128 * 2 * GUARD_BAND_PX as i128 / size as i128;
                let [edge, band] = [edge, band].map(|c| c.min(i64::MAX as i128 - 1) as i64);
                let xs = [0, 1, edge, edge + 1, band, band + 1, i64::MAX];
                let zs = [
                    0,
                    1,
                    w / 2,
                    w - 1,
                    w,
                    w + 1,
                    w + (1 << shift.max(0)),
                    -1,
                    i64::MIN,
                ];
                for &x in &xs {
                    for sign in [1, -1] {
                        for &z in &zs {
                            let c = sign * x;
                            for clip in [[c, -c / 3, z, w], [c / 5, c, z, w]] {
                                narrow += check_projection(clip, &vp) as u32;
                                all += 1;
                            }
                        }
                    }
                }
            }
        }
        assert!(narrow > 1000 && narrow < all, "{narrow} of {all}");
    }

    proptest::proptest! {
        /// Random vertices inside and around the guard band project as in 128 bits.
        #[test]
        fn narrow_projection_equals_128_bit_products(
            w in 1i64..1 << 62,
            x in -(1i64 << 40)..1 << 40,
            y in -(1i64 << 40)..1 << 40,
            z in -(1i64 << 10)..1 << 33,
            size in 1u32..=MAX_DIMENSION,
        ) {
            let vp = Viewport { width: size, height: size };
            // Coordinates as multiples of w / 2^32 (z up to twice w).
            let at = |c: i64| ((c as i128 * w as i128) >> 32) as i64;
            check_projection([at(x), at(y), at(z), w], &vp);
        }
    }
}
