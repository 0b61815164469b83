//! Viewpoint prediction (TerraVision's lesson: requests must leave ahead of the viewer). The
//! camera's recent motion is extrapolated `horizon` seconds ahead — position by its mean
//! velocity, viewing direction by its turn rate about the vertical — and the stream pager
//! prefetches what that predicted view needs. The predicted view is culled from an eye pulled
//! back along its viewing direction by a margin that grows with speed, so the faster the viewer
//! moves, the wider the area prefetched around the guess.

use std::collections::VecDeque;

use glam::DQuat;

use crate::engine::camera::Camera;

/// How far ahead and how wide to predict.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PredictionSettings {
    /// Seconds ahead of the current frame.
    pub horizon: f64,
    /// Seconds of recent motion the velocity and turn rate are measured over.
    pub window: f64,
    /// Margin at rest, metres.
    pub margin: f64,
    /// Margin added per metre per second of speed, seconds.
    pub margin_per_speed: f64,
}

impl Default for PredictionSettings {
    fn default() -> Self {
        PredictionSettings {
            horizon: 1.0,
            window: 0.5,
            margin: 0.0,
            margin_per_speed: 0.5,
        }
    }
}

/// A predicted view.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PredictedView {
    /// The camera extrapolated `horizon` seconds ahead: importance is measured from it.
    pub camera: Camera,
    /// The same camera pulled back by `margin` metres: tiles are culled against its frustum.
    pub cull: Camera,
    /// The margin, metres.
    pub margin: f64,
}

/// Extrapolates the camera from the frames it has seen.
#[derive(Clone, Debug)]
pub struct Predictor {
    settings: PredictionSettings,
    seen: VecDeque<(f64, Camera)>,
}

impl Predictor {
    /// A predictor that has seen nothing.
    pub fn new(settings: PredictionSettings) -> Self {
        Predictor {
            settings,
            seen: VecDeque::new(),
        }
    }

    /// The settings.
    pub fn settings(&self) -> &PredictionSettings {
        &self.settings
    }

    /// Records the camera of the frame drawn at `time` seconds (never earlier than the last).
    pub fn observe(&mut self, time: f64, camera: Camera) {
        if self.seen.back().is_some_and(|&(t, _)| time < t) {
            self.seen.clear();
        }
        self.seen.push_back((time, camera));
        while self
            .seen
            .front()
            .is_some_and(|&(t, _)| time - t > self.settings.window)
        {
            self.seen.pop_front();
        }
    }

    /// The view `horizon` seconds after the last frame seen; `None` before two frames at
    /// different times were seen.
    pub fn predict(&self) -> Option<PredictedView> {
        let camera = self.ahead(self.settings.horizon)?;
        let (&(t0, first), &(t1, last)) = (self.seen.front()?, self.seen.back()?);
        let speed = (last.position - first.position).length() / (t1 - t0);
        let margin = self.settings.margin + self.settings.margin_per_speed * speed;
        let cull = Camera {
            position: camera.position - camera.forward * margin,
            ..camera
        };
        Some(PredictedView {
            camera,
            cull,
            margin,
        })
    }

    /// The camera `seconds` after the last frame seen: position by the mean velocity, viewing
    /// direction by the turn rate; `None` before two frames at different times were seen.
    pub fn ahead(&self, seconds: f64) -> Option<Camera> {
        let (&(t0, first), &(t1, last)) = (self.seen.front()?, self.seen.back()?);
        let span = t1 - t0;
        if span <= 0.0 {
            return None;
        }
        let velocity = (last.position - first.position) / span;
        let turn = wrap_angle(last.heading() - first.heading()) / span;
        // Heading grows clockwise seen from above (y up): a negative rotation about +y.
        let forward = DQuat::from_rotation_y(-turn * seconds) * last.forward;
        Some(Camera {
            position: last.position + velocity * seconds,
            forward: forward.normalize_or(last.forward),
            ..last
        })
    }
}

/// `a` in `(-pi, pi]`.
fn wrap_angle(a: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    let a = a.rem_euclid(TAU);
    if a > PI { a - TAU } else { a }
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;

    /// A level camera at `position` looking along `heading_degrees` (clockwise from north).
    fn camera(position: DVec3, heading_degrees: f64) -> Camera {
        let h = heading_degrees.to_radians();
        Camera::looking_at(position, position + DVec3::new(h.sin(), 0.0, -h.cos()))
    }

    fn close(a: DVec3, b: DVec3) -> bool {
        (a - b).length() < 1e-9
    }

    #[test]
    fn straight_flight_is_extrapolated_and_the_margin_grows_with_speed() {
        let mut p = Predictor::new(PredictionSettings::default());
        assert!(p.predict().is_none());
        for k in 0..10 {
            let t = f64::from(k) * 0.1;
            p.observe(t, camera(DVec3::new(100.0 * t, 50.0, 0.0), 90.0));
        }
        let v = p.predict().unwrap();
        assert!(close(v.camera.position, DVec3::new(190.0, 50.0, 0.0)));
        assert!(close(v.camera.forward, DVec3::X));
        assert!((v.margin - 50.0).abs() < 1e-9);
        assert!(close(v.cull.position, DVec3::new(140.0, 50.0, 0.0)));
        // Half a second ahead (where a request sent now arrives, say), no margin.
        let soon = p.ahead(0.5).unwrap();
        assert!(close(soon.position, DVec3::new(140.0, 50.0, 0.0)));
        assert!(close(soon.forward, DVec3::X));
        // At rest the margin is the base margin and the view is the current one.
        let mut still = Predictor::new(PredictionSettings::default());
        still.observe(0.0, camera(DVec3::ZERO, 0.0));
        still.observe(0.5, camera(DVec3::ZERO, 0.0));
        let v = still.predict().unwrap();
        assert_eq!(v.margin, 0.0);
        assert!(close(v.camera.position, DVec3::ZERO));
    }

    #[test]
    fn a_turn_keeps_turning_across_north() {
        let mut p = Predictor::new(PredictionSettings::default());
        // 20° per second clockwise, through north (350° -> 10°).
        for k in 0..6 {
            let t = f64::from(k) * 0.1;
            p.observe(t, camera(DVec3::ZERO, 350.0 + 20.0 * t));
        }
        let v = p.predict().unwrap();
        let heading = v.camera.heading().to_degrees().rem_euclid(360.0);
        assert!((heading - 20.0).abs() < 1e-6, "{heading}");
    }

    #[test]
    fn old_frames_leave_the_window_and_time_going_back_restarts() {
        let mut p = Predictor::new(PredictionSettings::default());
        p.observe(0.0, camera(DVec3::ZERO, 0.0));
        p.observe(5.0, camera(DVec3::new(10.0, 0.0, 0.0), 0.0));
        assert!(
            p.predict().is_none(),
            "only the last frame is in the window"
        );
        p.observe(5.25, camera(DVec3::new(20.0, 0.0, 0.0), 0.0));
        let v = p.predict().unwrap();
        assert!(close(v.camera.position, DVec3::new(60.0, 0.0, 0.0)));
        p.observe(1.0, camera(DVec3::ZERO, 0.0));
        assert!(p.predict().is_none());
    }
}
