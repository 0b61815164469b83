//! The viewer: where it is, where it looks, and the eye-relative matrices built from that.
//!
//! World axes, used by the whole engine: x east, y up, z south, in metres, with (0, 0) at the
//! terrain's north-west sample (see [`crate::engine::terrain::TerrainFrame`] for placing the terrain
//! elsewhere). Matrices never contain the eye's absolute position: the view matrix looks from the
//! origin, and the renderer subtracts the eye from positions in f64 before anything is rounded.
//!
//! The caller gives a [`Camera`] (a pose); the engine was made for one [`Viewport`] (the
//! screen and the field of view, given once); a frame is drawn from the [`View`] they make with
//! the depth range the engine fits to the terrain.

use glam::{DMat4, DVec3};

use crate::engine::viewport::Viewport;

/// Where the eye is and where it looks: a pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position, world metres.
    pub position: DVec3,
    /// Unit viewing direction.
    pub forward: DVec3,
    /// Bank about the viewing direction, radians: positive rolls the camera clockwise as seen
    /// from behind (an aircraft banking right), so the horizon tilts the other way on screen.
    pub roll: f64,
}

impl Camera {
    /// A level camera at `position` looking at `target`.
    pub fn looking_at(position: DVec3, target: DVec3) -> Camera {
        Camera {
            position,
            forward: (target - position).normalize_or(DVec3::NEG_Z),
            roll: 0.0,
        }
    }

    /// A camera at `position` with an aircraft's attitude, radians: `heading` clockwise from
    /// north, `pitch` up from the horizon, `roll` banking right.
    pub fn from_attitude(position: DVec3, heading: f64, pitch: f64, roll: f64) -> Camera {
        Camera {
            position,
            forward: attitude_forward(heading, pitch),
            roll,
        }
    }

    /// The view matrix with the eye at the origin (eye-relative world to camera space).
    pub fn view_from_eye(&self) -> DMat4 {
        // An up vector parallel to the view direction has no meaning: fall back to north.
        let level = if self.forward.cross(DVec3::Y).length_squared() < 1e-12 {
            DVec3::NEG_Z
        } else {
            DVec3::Y
        };
        let up = if self.roll == 0.0 {
            level
        } else {
            // The level camera's up turned towards its right by the roll.
            let right = self.forward.cross(level).normalize();
            let up = right.cross(self.forward);
            let (sin, cos) = self.roll.sin_cos();
            up * cos + right * sin
        };
        glam::dcamera::rh::view::look_at_mat4(DVec3::ZERO, self.forward, up)
    }

    /// Heading in radians, clockwise from north, of the viewing direction.
    pub fn heading(&self) -> f64 {
        self.forward.x.atan2(-self.forward.z)
    }
}

/// The unit viewing direction (x east, y up, z south) of `heading` radians clockwise from
/// north and `pitch` radians up from the horizon.
pub fn attitude_forward(heading: f64, pitch: f64) -> DVec3 {
    let (sh, ch) = heading.sin_cos();
    let (sp, cp) = pitch.sin_cos();
    DVec3::new(sh * cp, sp, -ch * cp)
}

/// A camera seen through a viewport between two depth planes: what a frame is drawn from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    /// The pose.
    pub camera: Camera,
    /// The screen and the field of view.
    pub viewport: Viewport,
    /// Near plane distance, metres.
    pub near: f64,
    /// Far plane distance, metres.
    pub far: f64,
}

impl View {
    /// `camera` through `viewport` between `near` and `far` metres.
    pub fn new(camera: Camera, viewport: Viewport, near: f64, far: f64) -> View {
        View {
            camera,
            viewport,
            near,
            far,
        }
    }

    /// The projection to the rasterizer's clip space (depth 0 ..= 1).
    pub fn projection(&self) -> DMat4 {
        glam::dcamera::rh::proj::directx::perspective(
            self.viewport.fov_y,
            self.viewport.aspect(),
            self.near,
            self.far,
        )
    }

    /// Projection times eye-relative view: maps `world - position` to clip space.
    pub fn view_projection(&self) -> DMat4 {
        self.projection() * self.camera.view_from_eye()
    }

    /// Pixels per metre at distance `d`: the scale that turns a geometric error in metres
    /// into a screen-space error.
    pub fn pixels_per_metre(&self, d: f64) -> f64 {
        self.pixel_scale().at(d)
    }

    /// `pixels_per_metre` for many distances, with the field of view's tangent worked out once
    /// (on a core without an FPU a library call of about a thousand instructions).
    pub fn pixel_scale(&self) -> PixelScale {
        let v = &self.viewport;
        PixelScale {
            height: f64::from(v.height),
            span: 2.0 * (v.fov_y / 2.0).tan(),
            near: self.near,
        }
    }
}

/// A view's pixels per metre as a function of distance ([`View::pixel_scale`]).
#[derive(Clone, Copy, Debug)]
pub struct PixelScale {
    height: f64,
    /// The screen's height in metres at distance 1.
    span: f64,
    near: f64,
}

impl PixelScale {
    /// Pixels per metre at distance `d` (no nearer than the near plane): the same value as
    /// [`View::pixels_per_metre`], to the bit.
    pub fn at(&self, d: f64) -> f64 {
        self.height / (self.span * d.max(self.near))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec4;

    /// The view-projection of `cam` on a `width` x `height` screen, 60° tall, 1 m to 100 km.
    fn through(cam: &Camera, width: u32, height: u32) -> DMat4 {
        View::new(*cam, Viewport::new(width, height), 1.0, 1e5).view_projection()
    }

    /// Normalised device x and y of the eye-relative point `p`.
    fn screen(cam: &Camera, p: DVec3) -> (f64, f64) {
        let c = through(cam, 100, 100) * DVec4::from((p, 1.0));
        (c.x / c.w, c.y / c.w)
    }

    #[test]
    fn banking_right_tilts_the_world_counter_clockwise_on_screen() {
        let level = Camera::looking_at(DVec3::ZERO, DVec3::new(0.0, 0.0, -10.0));
        let above = DVec3::new(0.0, 1.0, -10.0);
        let (x, y) = screen(&level, above);
        assert!(x.abs() < 1e-12 && y > 0.0);
        let banked = Camera {
            roll: 90f64.to_radians(),
            ..level
        };
        // What is above the eye shows on the left; what is to the right, above.
        let (x, y) = screen(&banked, above);
        assert!(x < 0.0 && y.abs() < 1e-12, "{x} {y}");
        let (x, y) = screen(&banked, DVec3::new(1.0, 0.0, -10.0));
        assert!(x.abs() < 1e-12 && y > 0.0, "{x} {y}");
        let (a, b) = (
            screen(
                &Camera {
                    roll: 1e-300,
                    ..level
                },
                above,
            ),
            screen(&level, above),
        );
        assert!((a.0 - b.0).abs() < 1e-12 && (a.1 - b.1).abs() < 1e-12);
    }

    #[test]
    fn the_target_projects_to_the_centre_at_any_distance_from_the_origin() {
        for offset in [0.0, 1e3, 1e7, 1e8] {
            let base = DVec3::new(offset, 0.0, -offset);
            let cam = Camera::looking_at(base + DVec3::new(0.0, 500.0, 800.0), base);
            let rel = base - cam.position;
            let c = through(&cam, 400, 300) * DVec4::from((rel, 1.0));
            assert!(
                c.x.abs() / c.w < 1e-12 && c.y.abs() / c.w < 1e-12,
                "{offset}: {c}"
            );
            assert!((0.0..=1.0).contains(&(c.z / c.w)));
        }
    }

    #[test]
    fn looking_straight_down_still_has_a_view_matrix() {
        let cam = Camera::looking_at(DVec3::new(0.0, 100.0, 0.0), DVec3::ZERO);
        let m = through(&cam, 100, 100);
        assert!(m.to_cols_array().iter().all(|v| v.is_finite()));
        // North (-z) is up on screen.
        let north = m * DVec4::new(0.0, -100.0, -10.0, 1.0);
        assert!(north.y / north.w > 0.0);
    }

    #[test]
    fn heading_is_clockwise_from_north() {
        let at = |x: f64, z: f64| Camera::looking_at(DVec3::ZERO, DVec3::new(x, 0.0, z)).heading();
        assert!(at(0.0, -1.0).abs() < 1e-12);
        assert!((at(1.0, 0.0) - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!((at(0.0, 1.0).abs() - std::f64::consts::PI).abs() < 1e-12);
    }

    #[test]
    fn an_attitude_looks_where_its_heading_and_pitch_say() {
        let eye = DVec3::new(5.0, 100.0, -7.0);
        let east_and_down =
            Camera::from_attitude(eye, 90f64.to_radians(), -45f64.to_radians(), 0.0);
        let gaze = Camera::looking_at(eye, eye + DVec3::new(1.0, -1.0, 0.0));
        assert!((east_and_down.forward - gaze.forward).length() < 1e-12);
        assert!((east_and_down.heading() - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    }
}
