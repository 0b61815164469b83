//! Blocks inside the level: where every texture coordinate a buffer of fragments holds gives a
//! 2x2 block whose columns and rows lie in the level as they are, the colour stages one fragment
//! at a time skip the fold and the wrap of each (`Filtering::sample_one::<true>`). The engine's
//! tile textures are clamped at the tile's border only, so most of its buffers are inside.
//! Where the colour stage works in lanes or in NEON's passes, only the range's type is built
//! (`fragments::coords`).

use super::{LevelView, Quad, Texel};

/// The 16.16 texture coordinates of some fragments: each axis within `lo..=hi`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct UvRange {
    pub lo: [i32; 2],
    pub hi: [i32; 2],
}

#[cfg(any(test, not(any(wide_vectors, arm_neon))))]
impl UvRange {
    /// The range of no coordinate at all.
    pub const EMPTY: Self = Self {
        lo: [i32::MAX; 2],
        hi: [i32::MIN; 2],
    };

    /// The least range that holds both.
    #[inline(always)]
    pub fn union(self, other: Self) -> Self {
        Self {
            lo: [0, 1].map(|k| self.lo[k].min(other.lo[k])),
            hi: [0, 1].map(|k| self.hi[k].max(other.hi[k])),
        }
    }
}

impl<T: Texel> LevelView<'_, T> {
    /// True when every coordinate of `r` (not empty) gives a bilinear block inside the level as
    /// it is: `u` in `0..=0xFFFF`, so that folding it under either wrap leaves it, and the
    /// block's left column `x = (u * width - 2^15) >> 16` in `0..width - 1`, so that `x` and
    /// `x + 1` need no wrap either (`quad_taps` gives `quad_inside`'s block); rows alike. Both
    /// hold where `2^15 <= u * width < (width - 1) * 2^16 + 2^15` (whose upper end lies below
    /// `width * 2^16`, so `u < 2^16`), for the least and the greatest `u`. A nearest sample's
    /// texel lies inside such a level too.
    #[cfg(any(test, not(any(wide_vectors, arm_neon))))]
    pub fn holds_inside(&self, r: &UvRange) -> bool {
        let axis = |lo: i32, hi: i32, side: i64| {
            let half = 1 << 15;
            lo <= hi && lo as i64 * side >= half && hi as i64 * side - half < (side - 1) << 16
        };
        axis(r.lo[0], r.hi[0], self.width) && axis(r.lo[1], r.hi[1], self.height)
    }

    /// `scale_one` of coordinates in a range `holds_inside` accepts: their fold leaves them.
    #[inline(always)]
    pub fn scale_inside(&self, u: i32, v: i32) -> (i32, i32) {
        (u << self.width_shift, v << self.height_shift)
    }

    /// `scale_one`, or where `INSIDE` (the coordinates lie in a range `holds_inside` accepts)
    /// `scale_inside`.
    #[inline(always)]
    pub fn scale_for<const INSIDE: bool>(&self, u: i32, v: i32) -> (i32, i32) {
        if INSIDE {
            self.scale_inside(u, v)
        } else {
            self.scale_one(u, v)
        }
    }

    /// `quad_taps` of a block whose columns `x, x + 1` and rows `y, y + 1` lie in the level
    /// (`holds_inside`): neighbours in memory, with no wrap to apply.
    #[inline(always)]
    pub fn quad_inside(&self, x: i32, y: i32) -> Quad {
        let i = (y << self.width_shift) + x;
        let below = i + self.width as i32;
        Quad([i, i + 1, below, below + 1])
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;
    use crate::texture::Wrap;

    proptest! {
        /// Where a level holds a range inside, each coordinate of it gives the block and the
        /// scaled coordinate of `quad_taps` and `scale_one` under either wrap; a range reaching
        /// past that is not held inside.
        #[test]
        fn blocks_inside_the_level_need_no_wrap(
            shift in (0u32..8, 0u32..8),
            lo in (-(1i32 << 17)..1 << 17, -(1i32 << 17)..1 << 17),
            spread in (0i32..1 << 16, 0i32..1 << 16),
            at in (0.0f64..=1.0, 0.0f64..=1.0),
        ) {
            let (w, h) = (1u32 << shift.0, 1u32 << shift.1);
            let texels = vec![0u16; (w * h) as usize];
            let r = UvRange {
                lo: [lo.0, lo.1],
                hi: [lo.0 + spread.0, lo.1 + spread.1],
            };
            let pick = |k: usize, t: f64| r.lo[k] + ((r.hi[k] - r.lo[k]) as f64 * t) as i32;
            let (u, v) = (pick(0, at.0), pick(1, at.1));
            let inside = |side: u32, c: i32| {
                let t = (c << side.trailing_zeros()) - (1 << 15);
                t >= 0 && t >> 16 < side as i32 - 1
            };
            for wrap in [Wrap::Clamp, Wrap::Repeat] {
                let view = LevelView::new(&texels, w, h, wrap);
                let held = view.holds_inside(&r);
                // The ends of the range are where a block leaves the level first.
                let ends_inside = (0..2).all(|k| {
                    let side = [w, h][k];
                    inside(side, r.lo[k]) && inside(side, r.hi[k])
                });
                prop_assert_eq!(held, ends_inside, "{:?} {}x{}", r, w, h);
                if held {
                    let (su, sv) = view.scale_one(u, v);
                    prop_assert_eq!(view.scale_inside(u, v), (su, sv));
                    let (x, y) = ((su - (1 << 15)) >> 16, (sv - (1 << 15)) >> 16);
                    prop_assert_eq!(view.quad_inside(x, y).0, view.quad_taps(x, y).0);
                }
            }
        }
    }

    #[test]
    fn a_level_holds_a_range_inside_only_away_from_its_edges() {
        let texels = vec![0u16; 16 * 4];
        let view = LevelView::new(&texels, 16, 4, Wrap::Clamp);
        let range = |u: (i32, i32), v: (i32, i32)| UvRange {
            lo: [u.0, v.0],
            hi: [u.1, v.1],
        };
        // Texel centres of the first and the last column and row, and just inside them.
        let (u0, u1) = ((1 << 16) / 32, (1 << 16) - (1 << 16) / 32);
        let (v0, v1) = ((1 << 16) / 8, (1 << 16) - (1 << 16) / 8);
        assert!(view.holds_inside(&range((u0, u1 - 1), (v0, v1 - 1))));
        assert!(!view.holds_inside(&range((u0 - 1, u1 - 1), (v0, v1 - 1))));
        assert!(!view.holds_inside(&range((u0, u1), (v0, v1 - 1))));
        assert!(!view.holds_inside(&range((u0, u1 - 1), (v0 - 1, v1 - 1))));
        assert!(!view.holds_inside(&range((u0, u1 - 1), (v0, v1))));
        assert!(!view.holds_inside(&UvRange::EMPTY));
        // A level one texel wide has no block inside it.
        let narrow = LevelView::new(&texels[..4], 1, 4, Wrap::Repeat);
        assert!(!narrow.holds_inside(&range((1 << 15, 1 << 15), (v0, v0))));
        let both = range((5, 9), (-3, 2)).union(range((7, 20), (-8, -1)));
        assert_eq!(both, range((5, 20), (-8, 2)));
        assert_eq!(UvRange::EMPTY.union(both), both);
    }
}
