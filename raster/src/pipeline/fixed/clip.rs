//! Clip space of the integer pipeline: exact integer clip coordinates, outcodes against the
//! near and far planes and the guard band, and cuts that land exactly on the planes.

use crate::clip::{ClipVertex, Plane, outcode_by_planes};
use crate::fixed_point::{GUARD_BAND_PX, TEXCOORD_LIMIT};
use crate::matrix::FixedMat4;
use crate::pipeline::Viewport;
use crate::vertex::Vertex;

/// Most fractional bits of the clip-interpolation parameter.
const T_BITS_MAX: i32 = 61;

/// Guard band and viewport in the integer clip test `|x| * W <= 2 * GUARD_BAND_PX * w`.
pub(crate) struct FixedSpace {
    width: i128,
    height: i128,
}

impl FixedSpace {
    pub fn new(vp: &Viewport) -> Self {
        Self {
            width: vp.width as i128,
            height: vp.height as i128,
        }
    }
}

/// A vertex in clip space, exact integer clip coordinates plus attributes.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct FixedClip {
    pub(super) clip: [i64; 4],
    pub(super) uv: [i64; 2],
    pub(super) color: [i64; 3],
}

impl FixedClip {
    #[inline]
    pub fn from_vertex(v: &Vertex, m: &FixedMat4) -> Self {
        Self {
            clip: m.transform(v.position),
            uv: v
                .uv
                .map(|c| (c.to_bits() as i64).clamp(-TEXCOORD_LIMIT, TEXCOORD_LIMIT)),
            color: v.color.map(i64::from),
        }
    }

    fn distance(&self, plane: Plane, s: &FixedSpace) -> i128 {
        let [x, y, z, w] = self.clip.map(i128::from);
        let g = 2 * GUARD_BAND_PX as i128 * w;
        match plane {
            Plane::WMin => w - 1,
            Plane::Near => z,
            Plane::Far => w - z,
            Plane::Left => g + s.width * x,
            Plane::Right => g - s.width * x,
            Plane::Bottom => g + s.height * y,
            Plane::Top => g - s.height * y,
        }
    }
}

/// Clip coordinates below this (in magnitude) take `FixedClip::outcode`'s i64 test: with them
/// `2 * GUARD_BAND_PX * w` stays below 2^62 and `side * x` below `2^13 * 2^46 = 2^59`
/// (`MAX_DIMENSION` is 2^13), so every distance fits in i64.
const NARROW_CLIP: u64 = 1 << 46;

impl ClipVertex for FixedClip {
    type Space = FixedSpace;

    /// The distances of `distance` in i64 when the coordinates allow it (every vertex of a
    /// terrain view: the transform's block floating point keeps its largest entry near 2^29),
    /// else plane by plane in i128. The same bits either way (tested).
    #[inline]
    fn outcode(&self, s: &FixedSpace) -> u8 {
        let [x, y, z, w] = self.clip;
        if (x.unsigned_abs() | y.unsigned_abs() | z.unsigned_abs() | w.unsigned_abs())
            >= NARROW_CLIP
        {
            return outcode_by_planes(self, s);
        }
        let g = 2 * GUARD_BAND_PX * w;
        let (sx, sy) = (s.width as i64 * x, s.height as i64 * y);
        let out = |outside: bool, p: Plane| outside as u8 * p as u8;
        out(w < 1, Plane::WMin)
            | out(z < 0, Plane::Near)
            | out(w - z < 0, Plane::Far)
            | out(g + sx < 0, Plane::Left)
            | out(g - sx < 0, Plane::Right)
            | out(g + sy < 0, Plane::Bottom)
            | out(g - sy < 0, Plane::Top)
    }

    #[inline]
    fn inside(&self, plane: Plane, s: &FixedSpace) -> bool {
        self.distance(plane, s) >= 0
    }

    fn intersect(a: &Self, b: &Self, plane: Plane, s: &FixedSpace) -> Self {
        let (da, db) = (a.distance(plane, s), b.distance(plane, s));
        // t = da / (da - db) in 0..=1, with as many fraction bits as keep `da << bits` and
        // `(q - p) * t` (|q - p| < 2^64) inside i128: a cut far along a long segment stays exact.
        let bits = (T_BITS_MAX)
            .min(125 - (128 - da.leading_zeros()) as i32)
            .max(0);
        let t = (da << bits) / (da - db);
        let lerp = |p: i64, q: i64| (p as i128 + (((q as i128 - p as i128) * t) >> bits)) as i64;
        let mut v = Self {
            clip: [0, 1, 2, 3].map(|k| lerp(a.clip[k], b.clip[k])),
            uv: [0, 1].map(|k| lerp(a.uv[k], b.uv[k])),
            color: [0, 1, 2].map(|k| lerp(a.color[k], b.color[k])),
        };
        // Land exactly on the planes whose violation would break the divide or the depth range.
        match plane {
            Plane::WMin => v.clip[3] = v.clip[3].max(1),
            Plane::Near => v.clip[2] = 0,
            Plane::Far => v.clip[2] = v.clip[3],
            _ => {}
        }
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixed_point::MAX_DIMENSION;

    /// The i64 outcode against the 128-bit distances, plane by plane.
    fn check_outcode(clip: [i64; 4], size: u32) {
        let vp = Viewport {
            width: size,
            height: (size / 3).max(1),
        };
        let s = FixedSpace::new(&vp);
        let v = FixedClip {
            clip,
            ..FixedClip::default()
        };
        assert_eq!(v.outcode(&s), outcode_by_planes(&v, &s), "{clip:?} {size}");
    }

    #[test]
    fn outcodes_in_i64_equal_128_bit_distances_at_the_bounds() {
        let n = NARROW_CLIP as i64;
        let at = [0, 1, 2, n / 2, n - 1, n, i64::MAX, i64::MIN, i64::MIN + 1];
        let coords: Vec<i64> = at.iter().flat_map(|&c| [c, c.saturating_neg()]).collect();
        for size in [1, 320, MAX_DIMENSION] {
            for &w in &coords {
                // Points on and beside the guard band's planes for this w, and the bounds.
                let band = (2 * GUARD_BAND_PX as i128 * w as i128 / size as i128)
                    .clamp(i64::MIN as i128 + 2, i64::MAX as i128 - 2)
                    as i64;
                let xs: Vec<i64> = coords
                    .iter()
                    .copied()
                    .chain([band - 1, band, band + 1, -band - 1, -band, -band + 1])
                    .collect();
                for &x in &xs {
                    for &z in &[0, -1, w, w.saturating_add(1), w.saturating_sub(1), x] {
                        check_outcode([x, x.saturating_neg() / 3, z, w], size);
                        check_outcode([x / 7, x, z, w], size);
                    }
                }
            }
        }
    }

    proptest::proptest! {
        /// Random clip coordinates on both sides of the i64 test's bound give the outcode of the
        /// 128-bit distances.
        #[test]
        fn outcodes_in_i64_equal_128_bit_distances(
            x in -(1i64 << 48)..1 << 48,
            y in -(1i64 << 48)..1 << 48,
            z in -(1i64 << 48)..1 << 48,
            w in -(1i64 << 20)..1 << 48,
            size in 1u32..=MAX_DIMENSION,
        ) {
            check_outcode([x, y, z, w], size);
            // Scaled towards the guard band's planes, where the sign of a distance is close.
            let band = 2 * GUARD_BAND_PX * (w >> 17) / size as i64;
            check_outcode([band + x % 3, -band - y % 3, z, w >> 17], size);
        }
    }
}
