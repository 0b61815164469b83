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
        }
    }

    /// False only when the box is certainly outside (entirely behind one plane).
    pub fn intersects(&self, aabb: &Aabb) -> bool {
        self.planes.iter().zip(&self.toward).all(|(p, &toward)| {
            let n = p.truncate();
            // The corner farthest along the plane's normal.
            let corner = DVec3::select(toward, aabb.max, aabb.min);
            let reach = n.dot(corner) + p.w;
            // A corner on the inside needs no slack (it is never negative, and NaN only with
            // `reach`): on a core without an FPU its products are library calls, so only the
            // boxes outside a plane pay for them.
            reach >= 0.0 || reach >= -SLACK * (n.abs().dot(corner.abs()) + p.w.abs())
        })
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

    proptest! {
        #[test]
        fn the_slack_only_for_corners_outside_a_plane_culls_the_same_boxes(
            m in camera(),
            a in prop::array::uniform3(coordinate()),
            b in prop::array::uniform3(coordinate()),
        ) {
            let (a, b) = (DVec3::from(a), DVec3::from(b));
            let aabb = Aabb::new(a.min(b), a.max(b));
            let f = Frustum::from_view_projection(&m);
            prop_assert_eq!(f.intersects(&aabb), intersects_with_slack_always(&f, &aabb));
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
