//! Frustum culling of tile bounding boxes: only tiles in the view frustum take part in the
//! paper's visual importance (Algorithm 2) and share the triangle budget.
//!
//! The six planes come from the f64 view-projection matrix (Gribb & Hartmann) for the clip
//! convention the rasterizer uses, `glam::dcamera::rh::proj::directx`: `-w <= x, y <= w` and
//! `0 <= z <= w`. A box is culled only when it lies entirely on the outer side of one plane, so a
//! visible box is never culled; a box outside the frustum near one of its edges may be kept,
//! which costs a draw that clips away, never a hole.
//!
//! Boxes and matrix must be in the same space. The engine can use world coordinates (f64 holds
//! them exactly enough far from the origin) or, as for drawing, eye-relative ones.

use glam::{BVec3, DMat4, DVec3, DVec4};

use crate::engine::normals::FLOATS_IN_SOFTWARE;

/// An axis-aligned bounding box, e.g. a tile's extent and its elevation range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Smallest corner.
    pub min: DVec3,
    /// Largest corner.
    pub max: DVec3,
}

impl Aabb {
    /// The box between two corners (`min <= max` in every coordinate).
    pub fn new(min: DVec3, max: DVec3) -> Self {
        debug_assert!(min.cmple(max).all(), "{min} > {max}");
        Self { min, max }
    }

    /// Distance from `point` to the nearest point of the box, 0 inside: the tile distance that
    /// visual importance uses.
    pub fn distance(&self, point: DVec3) -> f64 {
        point.clamp(self.min, self.max).distance(point)
    }
}

/// The view frustum as six inward-facing planes `(n, d)`: a point `p` is inside when
/// `n . p + d >= 0` for all of them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frustum {
    planes: [DVec4; 6],
    /// Which way each plane's normal points along each axis (`n >= 0`): which corner of a box
    /// lies farthest inside, found once per frustum rather than once per box, where on a core
    /// without an FPU each comparison is a library call.
    toward: [BVec3; 6],
    /// The planes in integers, for the quick decision where floats are library calls
    /// (`FixedPlane`); `None` for a plane out of their range.
    fixed: [Option<FixedPlane>; 6],
}

/// Relative slack of the plane test, so that rounding never culls a box that touches a plane.
const SLACK: f64 = 1e-12;

impl Frustum {
    /// The frustum of `view_projection` (projection × view), clip depth 0..1.
    pub fn from_view_projection(view_projection: &DMat4) -> Self {
        let [x, y, z, w] = [0, 1, 2, 3].map(|i| view_projection.row(i));
        let planes = [w + x, w - x, w + y, w - y, z, w - z];
        Self {
            planes,
            toward: planes.map(|p| p.truncate().cmpge(DVec3::ZERO)),
            fixed: planes.map(FixedPlane::of),
        }
    }

    /// False only when the box is certainly outside (entirely behind one plane).
    ///
    /// Where floats are library calls (`FLOATS_IN_SOFTWARE`), each plane is first decided in
    /// integers (`FixedPlane::decide`), and only a box too close to the plane for them to be
    /// sure, or out of their range, takes the `f64` test: the same answer in a few dozen
    /// instructions instead of a dozen library calls.
    pub fn intersects(&self, aabb: &Aabb) -> bool {
        self.intersects_by::<FLOATS_IN_SOFTWARE>(aabb)
    }

    /// `intersects`, with the integers' quick decision or without.
    fn intersects_by<const QUICK: bool>(&self, aabb: &Aabb) -> bool {
        if QUICK && let Some(b) = FixedBox::of(aabb) {
            return (0..6).all(|i| {
                let quick = self.fixed[i].and_then(|p| p.decide(&b, self.toward[i]));
                quick.unwrap_or_else(|| self.inside_plane(i, aabb))
            });
        }
        (0..6).all(|i| self.inside_plane(i, aabb))
    }

    /// Whether the box is not entirely behind plane `i`, in `f64`.
    fn inside_plane(&self, i: usize, aabb: &Aabb) -> bool {
        let p = self.planes[i];
        let n = p.truncate();
        // The corner farthest along the plane's normal.
        let corner = DVec3::select(self.toward[i], aabb.max, aabb.min);
        let reach = n.dot(corner) + p.w;
        // A corner on the inside needs no slack (it is never negative, and NaN only with
        // `reach`): on a core without an FPU its products are library calls, so only the
        // boxes outside a plane pay for them.
        reach >= 0.0 || reach >= -SLACK * (n.abs().dot(corner.abs()) + p.w.abs())
    }
}

/// Fraction bits of a box's coordinates in integers (`FixedBox`): 1/256 metre.
const BOX_BITS: i32 = 8;

/// A box's corners in integers, `c * 2^BOX_BITS` truncated toward zero (less than one unit
/// off), for coordinates within `2^23` (8,388 km; eye-relative boxes of any terrain in view).
#[derive(Clone, Copy, Debug)]
struct FixedBox {
    min: [i32; 3],
    max: [i32; 3],
}

impl FixedBox {
    /// The box in integers, `None` when a coordinate is out of range, infinite or NaN.
    fn of(aabb: &Aabb) -> Option<Self> {
        let fixed = |v: DVec3| -> Option<[i32; 3]> {
            Some([
                fixed_coordinate(v.x)?,
                fixed_coordinate(v.y)?,
                fixed_coordinate(v.z)?,
            ])
        };
        Some(Self {
            min: fixed(aabb.min)?,
            max: fixed(aabb.max)?,
        })
    }
}

/// `c * 2^BOX_BITS` truncated toward zero, read off the bits of `c` (a conversion is a library
/// call without an FPU), when `|c| < 2^23`; `None` otherwise (also infinite and NaN).
fn fixed_coordinate(c: f64) -> Option<i32> {
    const MANTISSA: u32 = 52;
    const BIAS: i32 = 1023;
    let bits = c.to_bits();
    let exponent = ((bits >> MANTISSA) & 0x7ff) as i32;
    if exponent >= BIAS + 23 {
        return None;
    }
    // |c| = m 2^(exponent - BIAS - MANTISSA); subnormals (exponent 0) are far below one unit.
    let m = (bits & ((1 << MANTISSA) - 1)) | 1 << MANTISSA;
    let shift = (BIAS + MANTISSA as i32 - BOX_BITS - exponent) as u32;
    let magnitude = m.checked_shr(shift).unwrap_or(0) as i32;
    Some(if bits >> 63 != 0 {
        -magnitude
    } else {
        magnitude
    })
}

/// A plane `(n, w)` in integers: `N = round(n 2^a)` with its largest component in
/// `[2^28, 2^29]`, and `W = round(w 2^(a + BOX_BITS))`, below `2^60`. With a box's corner `C`
/// in integers (`FixedBox`), `R = N . C + W` is `X = 2^(a + BOX_BITS) (n . c + w)` within
/// `E = Σ|N| + Σ|C| / 2 + 2` (each product `N C` strays from `ν γ = n 2^a c 2^BOX_BITS` by at
/// most `|N| |C - γ| + |N - ν| |γ| < |N| + (|C| + 1) / 2`, and `W` from its value by 1/2), all
/// in i64: `|N C| < 2^60`, so `|R| < 2^62`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct FixedPlane {
    n: [i32; 3],
    w: i64,
    /// `Σ|N|`, the part of `E` that does not depend on the box.
    n_sum: i64,
}

impl FixedPlane {
    /// The plane in integers, `None` when its normal is zero or not finite or `w` too large.
    fn of(p: DVec4) -> Option<Self> {
        let largest = p.truncate().abs().max_element();
        if !(largest.is_finite() && largest > 0.0) {
            return None;
        }
        let a = 28 - largest.log2().floor() as i32;
        // Powers of two far from both ends of `f64`'s range scale exactly.
        if !(-900..=900).contains(&a) {
            return None;
        }
        let scale = |v: f64, bits: i32| v * 2f64.powi(bits);
        let n = p.truncate().to_array().map(|c| scale(c, a).round());
        let w = scale(p.w, a + BOX_BITS).round();
        // `largest.log2()` may round across a power of two: the components stay within 2^29.
        let fits =
            n.iter().all(|c| c.abs() <= (1u64 << 29) as f64) && w.abs() < (1u64 << 60) as f64;
        fits.then(|| {
            let n = n.map(|c| c as i32);
            Self {
                n,
                w: w as i64,
                n_sum: n.iter().map(|&c| i64::from(c.unsigned_abs())).sum(),
            }
        })
    }

    /// `Frustum::inside_plane`'s answer for `b` when the integers are sure of it, `None` when
    /// the corner lies too close to the plane (`toward`: the corner farthest along the normal).
    ///
    /// The `f64` reach rounds `X` by less than `F = 2^-50 S` for `S = 2^(a + BOX_BITS)
    /// (Σ|n c| + |w|)` (four roundings of sums and products of those magnitudes), and its slack
    /// is `10^-12 S < 2^-39 S` give or take the same. So `R > E + F` means the corner is inside
    /// (`reach >= 0`), and `R + E + F + 2^-38 S < 0` that the plane culls the box; `S` is bounded
    /// by `Σ (|N| + 1)(|C| + 1) + |W| + 1`, below `2^62 + 2^34`, and every sum stays in i64.
    #[inline]
    fn decide(&self, b: &FixedBox, toward: BVec3) -> Option<bool> {
        let toward = [toward.x, toward.y, toward.z];
        let c: [i32; 3] = std::array::from_fn(|k| if toward[k] { b.max[k] } else { b.min[k] });
        let r = (0..3).fold(self.w, |r, k| r + i64::from(self.n[k]) * i64::from(c[k]));
        let c_sum: i64 = c.iter().map(|&v| i64::from(v.unsigned_abs())).sum();
        let e = self.n_sum + (c_sum >> 1) + 3;
        // `F` is at most `2^12 + 1` for any box (`S < 2^62 + 2^34`): a corner inside needs no `S`.
        const F_MOST: i64 = (1 << 12) + 1;
        if r > e + F_MOST {
            return Some(true);
        }
        let s = (0..3).fold(self.w.unsigned_abs() + 1, |s, k| {
            s + (u64::from(self.n[k].unsigned_abs()) + 1) * (u64::from(c[k].unsigned_abs()) + 1)
        });
        let f = (s >> 50) as i64 + 1;
        if r + e + f + (s >> 38) as i64 + 1 < 0 {
            Some(false)
        } else {
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::dcamera::rh::{proj::directx::perspective, view::look_at_mat4};
    use proptest::prelude::*;

    use super::*;

    /// A camera at `eye` looking north (-Z), 60° vertical field of view, 4:3, depth 1..1000.
    fn frustum(eye: DVec3) -> Frustum {
        let m = perspective(60f64.to_radians(), 4.0 / 3.0, 1.0, 1000.0)
            * look_at_mat4(eye, eye + DVec3::NEG_Z, DVec3::Y);
        Frustum::from_view_projection(&m)
    }

    fn cube(center: DVec3, half: f64) -> Aabb {
        Aabb::new(center - half, center + half)
    }

    #[test]
    fn boxes_in_front_behind_beside_and_straddling() {
        for eye in [DVec3::ZERO, DVec3::new(1e7, 500.0, -3e7)] {
            let f = frustum(eye);
            let at = |x: f64, y: f64, z: f64, half: f64| {
                f.intersects(&cube(eye + DVec3::new(x, y, z), half))
            };
            assert!(at(0.0, 0.0, -10.0, 1.0), "in front");
            assert!(at(0.0, 0.0, -999.0, 0.5), "in front, near the far plane");
            assert!(!at(0.0, 0.0, 10.0, 1.0), "behind");
            assert!(!at(100.0, 0.0, -10.0, 1.0), "east of the view");
            assert!(!at(-100.0, 0.0, -10.0, 1.0), "west of the view");
            assert!(!at(0.0, 100.0, -10.0, 1.0), "above the view");
            assert!(!at(0.0, -100.0, -10.0, 1.0), "below the view");
            assert!(
                !at(0.0, 0.0, -0.5, 0.2),
                "between the eye and the near plane"
            );
            assert!(!at(0.0, 0.0, -2000.0, 10.0), "beyond the far plane");
            assert!(at(0.0, 0.0, -1.0, 0.5), "straddling the near plane");
            assert!(at(0.0, 0.0, -1000.0, 10.0), "straddling the far plane");
            assert!(at(10.0, 0.0, -10.0, 4.0), "straddling the east plane");
            assert!(at(0.0, 0.0, 0.0, 5.0), "containing the eye");
            assert!(
                f.intersects(&Aabb::new(
                    eye + DVec3::new(-1e4, -50.0, -1e4),
                    eye + DVec3::new(1e4, -40.0, 1e4)
                )),
                "ground under the camera, reaching into the view"
            );
        }
    }

    #[test]
    fn distance_to_a_box_is_zero_inside_and_euclidean_outside() {
        let b = Aabb::new(DVec3::ZERO, DVec3::new(2.0, 1.0, 2.0));
        assert_eq!(b.distance(DVec3::new(1.0, 0.5, 1.0)), 0.0);
        assert_eq!(b.distance(DVec3::new(1.0, 4.0, 1.0)), 3.0);
        assert_eq!(b.distance(DVec3::new(5.0, 5.0, 2.0)), 5.0);
    }

    fn camera() -> impl Strategy<Value = DMat4> {
        (
            prop::array::uniform3(-1e4..1e4f64),
            prop::array::uniform3(-1.0..1.0f64),
            0.2..2.5f64,
            0.5..3.0f64,
            0.1..10.0f64,
            10.0..1e4f64,
        )
            .prop_filter_map("a direction", |(eye, dir, fov, aspect, near, far_ratio)| {
                let eye = DVec3::from(eye);
                let dir = DVec3::from(dir);
                (dir.length() > 0.1 && dir.normalize().y.abs() < 0.99).then(|| {
                    perspective(fov, aspect, near, near * far_ratio)
                        * look_at_mat4(eye, eye + dir, DVec3::Y)
                })
            })
    }

    /// Whether `p` satisfies every clip inequality of `m`, by transforming it.
    fn clip_inside(m: &DMat4, p: DVec3) -> [bool; 6] {
        let c = *m * p.extend(1.0);
        [
            c.x >= -c.w,
            c.x <= c.w,
            c.y >= -c.w,
            c.y <= c.w,
            c.z >= 0.0,
            c.z <= c.w,
        ]
    }

    /// `Frustum::intersects` with the slack worked out for every plane.
    fn intersects_with_slack_always(f: &Frustum, aabb: &Aabb) -> bool {
        f.planes.iter().all(|p| {
            let n = p.truncate();
            let corner = DVec3::select(n.cmpge(DVec3::ZERO), aabb.max, aabb.min);
            let size = n.abs().dot(corner.abs()) + p.w.abs();
            n.dot(corner) + p.w >= -SLACK * size
        })
    }

    /// A box coordinate: ordinary, huge, or infinite.
    fn coordinate() -> impl Strategy<Value = f64> {
        prop_oneof![
            8 => -2e4..2e4f64,
            1 => prop::sample::select(vec![f64::INFINITY, f64::NEG_INFINITY, 1e300, -1e300]),
        ]
    }

    /// A box with one corner `d` metres from a point on a side of the frustum of `m` (chosen by
    /// `side`, at `ndc` on it), reaching `size` metres from there.
    fn box_at_a_side(m: &DMat4, side: usize, ndc: [f64; 2], d: DVec3, size: DVec3) -> Aabb {
        let (u, v) = (ndc[0], ndc[1]);
        let on = match side {
            0 => DVec3::new(-1.0, u, (v + 1.0) / 2.0),
            1 => DVec3::new(1.0, u, (v + 1.0) / 2.0),
            2 => DVec3::new(u, -1.0, (v + 1.0) / 2.0),
            3 => DVec3::new(u, 1.0, (v + 1.0) / 2.0),
            4 => DVec3::new(u, v, 0.0),
            _ => DVec3::new(u, v, 1.0),
        };
        let p = m.inverse().project_point3(on) + d;
        Aabb::new(p.min(p + size), p.max(p + size))
    }

    /// Asserts that every plane the integers decide for `b` they decide as the `f64` test
    /// does, and that the quick test answers as the `f64` one; returns how many planes of the
    /// six the integers decided.
    fn assert_decided_as_the_floats(f: &Frustum, b: &Aabb) -> usize {
        assert_eq!(
            f.intersects_by::<true>(b),
            f.intersects_by::<false>(b),
            "{b:?}"
        );
        let Some(fixed) = FixedBox::of(b) else {
            return 0;
        };
        let decided = (0..6).filter_map(|k| {
            let v = f.fixed[k].and_then(|p| p.decide(&fixed, f.toward[k]))?;
            assert_eq!(v, f.inside_plane(k, b), "{b:?} plane {k}");
            Some(())
        });
        decided.count()
    }

    #[test]
    fn the_integers_decide_most_boxes_and_as_the_floats_do() {
        // Eye-relative boxes around a camera at the origin, up to 1 km away and 125 m wide.
        let f = frustum(DVec3::ZERO);
        let (mut decided, mut asked) = (0, 0);
        for i in 0..2000u64 {
            let h = |k: u64| ((i * 7919 + k * 104_729) % 2000) as f64 - 1000.0;
            let c = DVec3::new(h(1), h(2) / 4.0, h(3));
            let b = Aabb::new(
                c,
                c + DVec3::new(h(4).abs(), h(5).abs() / 10.0, h(6).abs()) / 8.0,
            );
            assert!(FixedBox::of(&b).is_some() && f.fixed.iter().all(Option::is_some));
            decided += assert_decided_as_the_floats(&f, &b);
            asked += 6;
        }
        assert!(decided * 100 > asked * 99, "{decided} of {asked}");
    }

    #[test]
    fn coordinates_in_integers_are_truncated_within_range_and_refused_beyond() {
        let unit = f64::from(1 << BOX_BITS);
        for c in [
            0.0, -0.0, 1e-320, 0.001, 0.5, 1.0, -1.0, 3.999, 1234.5678, -8e6, 8388607.99,
        ] {
            let fixed = fixed_coordinate(c).expect("in range");
            assert_eq!(fixed, (c * unit).trunc() as i32, "{c}");
        }
        for c in [
            8388608.0,
            -8388608.0,
            1e300,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
        ] {
            assert_eq!(fixed_coordinate(c), None, "{c}");
        }
    }

    proptest! {
        #[test]
        fn coordinates_in_integers_are_the_truncated_products(c in -8388607.0..8388607.0f64) {
            let unit = f64::from(1 << BOX_BITS);
            prop_assert_eq!(fixed_coordinate(c), Some((c * unit).trunc() as i32));
        }

        /// Boxes a hair's breadth from a side, where the integers must leave the answer to the
        /// floats, and boxes anywhere: the quick test answers as the `f64` one.
        #[test]
        fn the_integers_answer_as_the_floats_next_to_every_side(
            m in camera(),
            side in 0usize..6,
            ndc in prop::array::uniform2(-1.0..1.0f64),
            scale in -12i32..4,
            d in prop::array::uniform3(-1.0..1.0f64),
            size in prop::array::uniform3(0.0..50.0f64),
        ) {
            let d = DVec3::from(d) * 10f64.powi(scale);
            let b = box_at_a_side(&m, side, ndc, d, DVec3::from(size));
            assert_decided_as_the_floats(&Frustum::from_view_projection(&m), &b);
        }

        #[test]
        fn the_slack_only_for_corners_outside_a_plane_culls_the_same_boxes(
            m in camera(),
            a in prop::array::uniform3(coordinate()),
            b in prop::array::uniform3(coordinate()),
        ) {
            let (a, b) = (DVec3::from(a), DVec3::from(b));
            let aabb = Aabb::new(a.min(b), a.max(b));
            let f = Frustum::from_view_projection(&m);
            prop_assert_eq!(f.intersects_by::<false>(&aabb), intersects_with_slack_always(&f, &aabb));
            prop_assert_eq!(f.intersects_by::<true>(&aabb), intersects_with_slack_always(&f, &aabb));
        }

        #[test]
        fn a_box_around_a_visible_point_is_never_culled(
            m in camera(),
            ndc in prop::array::uniform3(-0.999..0.999f64),
            half in prop::array::uniform3(0.0..100.0f64),
            split in prop::array::uniform3(0.0..1.0f64),
        ) {
            let depth = (ndc[2] + 1.0) / 2.0;
            let p = m.inverse().project_point3(DVec3::new(ndc[0], ndc[1], depth));
            let half = DVec3::from(half);
            let split = DVec3::from(split);
            let b = Aabb::new(p - 2.0 * half * split, p + 2.0 * half * (1.0 - split));
            prop_assert!(Frustum::from_view_projection(&m).intersects(&b), "{p} in {b:?}");
        }

        #[test]
        fn a_culled_box_has_all_corners_outside_one_clip_plane(
            m in camera(),
            center in prop::array::uniform3(-2e4..2e4f64),
            half in prop::array::uniform3(0.0..5e3f64),
        ) {
            let (c, h) = (DVec3::from(center), DVec3::from(half));
            let b = Aabb::new(c - h, c + h);
            if !Frustum::from_view_projection(&m).intersects(&b) {
                let corners: Vec<[bool; 6]> = (0..8)
                    .map(|k| {
                        let pick = DVec3::new((k & 1) as f64, ((k >> 1) & 1) as f64, (k >> 2) as f64);
                        clip_inside(&m, b.min + (b.max - b.min) * pick)
                    })
                    .collect();
                prop_assert!((0..6).any(|plane| corners.iter().all(|c| !c[plane])));
            }
        }
    }
}
