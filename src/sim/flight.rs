//! Flight paths: timed keyframes of eye and gaze, built in or read from TOML
//! (`sim::flight_file`, with the `lab` feature).
//!
//! Between keyframes, positions and gaze targets follow a cubic Hermite curve with Catmull-Rom
//! tangents (finite differences over time), so a path through the keys is smooth and passes
//! through every one of them. A flight may be *terrain-following*: its heights are then metres
//! above the ground under the eye, which the engine adds when it knows the ground there.

use glam::DVec3;

use crate::engine::terrain::TerrainFrame;
use crate::named::{Named, named_enum};

/// One keyframe.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Key {
    /// Seconds from the start.
    pub t: f64,
    /// Eye position, terrain-frame metres.
    pub position: DVec3,
    /// Point looked at, terrain-frame metres.
    pub target: DVec3,
    /// Bank about the viewing direction, radians, positive to the right (see
    /// [`Camera::roll`](crate::engine::camera::Camera::roll)).
    pub roll: f64,
}

/// A timed path for the eye.
#[derive(Clone, Debug, PartialEq)]
pub struct Flight {
    /// Name for reports.
    pub name: String,
    /// When true, key heights are metres above the ground under the eye.
    pub above_ground: bool,
    keys: Vec<Key>,
}

/// The flights every archive gets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Builtin {
    /// A slow circle around the centre, looking at it from high up.
    Overview,
    /// The paper's flyover: north-west corner to south-east corner, looking ahead and down.
    Diagonal,
    /// Terrain-following at low altitude on a winding path across the middle.
    Low,
}

named_enum!(Builtin, "built-in flight", {
    Overview => "overview",
    Diagonal => "diagonal",
    Low => "low",
});

impl Flight {
    /// A flight through `keys`, which must be at least one, finite and strictly increasing in time.
    pub fn new(
        name: &str,
        above_ground: bool,
        keys: Vec<Key>,
    ) -> std::result::Result<Self, String> {
        if keys.is_empty() {
            return Err("a flight needs at least one key".into());
        }
        for (k, key) in keys.iter().enumerate() {
            let finite = key.t.is_finite()
                && key.position.is_finite()
                && key.target.is_finite()
                && key.roll.is_finite();
            if !finite {
                return Err(format!("key {k} holds a non-finite number"));
            }
            if key.position == key.target {
                return Err(format!("key {k} looks at its own position"));
            }
        }
        if let Some(k) = keys.windows(2).position(|w| w[1].t <= w[0].t) {
            return Err(format!("key {} is not later than key {k}", k + 1));
        }
        Ok(Flight {
            name: name.to_string(),
            above_ground,
            keys,
        })
    }

    /// A built-in flight scaled to the terrain.
    pub fn builtin(which: Builtin, terrain: &TerrainFrame) -> Flight {
        let (w, d) = terrain.source_extent();
        let (_, top) = terrain.heights;
        let size = w.max(d);
        let at = |fx: f64, y: f64, fz: f64| DVec3::new(fx * w, y, fz * d);
        let (above_ground, keys): (bool, Vec<Key>) = match which {
            Builtin::Overview => {
                let centre = at(0.5, 0.0, 0.5);
                let radius = 0.3 * w.min(d);
                let height = top + 0.15 * size;
                let keys = (0..=16)
                    .map(|k| {
                        let a = std::f64::consts::TAU * k as f64 / 16.0;
                        Key {
                            t: 60.0 * k as f64 / 16.0,
                            position: centre
                                + DVec3::new(radius * a.sin(), height, -radius * a.cos()),
                            target: centre,
                            roll: 0.0,
                        }
                    })
                    .collect();
                (false, keys)
            }
            Builtin::Diagonal => {
                let height = 0.6 * top + 0.02 * size;
                let keys = (0..=8)
                    .map(|k| {
                        let f = 0.05 + 0.9 * k as f64 / 8.0;
                        let ahead = (f + 0.08).min(1.0);
                        Key {
                            t: 60.0 * k as f64 / 8.0,
                            position: at(f, height, f),
                            target: at(ahead, 0.0, ahead),
                            roll: 0.0,
                        }
                    })
                    .collect();
                (false, keys)
            }
            Builtin::Low => {
                let clearance = 150.0;
                let keys = (0..=12)
                    .map(|k| {
                        let f = k as f64 / 12.0;
                        let path = |f: f64| {
                            let x = 0.1 + 0.8 * f;
                            let z = 0.5 + 0.2 * (f * std::f64::consts::TAU * 1.5).sin();
                            at(x, clearance, z)
                        };
                        let (here, next) = (path(f), path(f + 0.02));
                        let ahead = here + (next - here).normalize() * 0.05 * size;
                        Key {
                            t: 60.0 * f,
                            position: here,
                            target: DVec3::new(ahead.x, clearance - 0.01 * size, ahead.z),
                            roll: 0.0,
                        }
                    })
                    .collect();
                (true, keys)
            }
        };
        Flight::new(which.name(), above_ground, keys).expect("built-in flights are well formed")
    }

    /// Seconds from the first key to the last.
    pub fn duration(&self) -> f64 {
        self.keys.last().expect("non-empty").t - self.keys[0].t
    }

    /// Eye position and gaze target at `t` seconds (clamped to the flight).
    pub fn at(&self, t: f64) -> (DVec3, DVec3) {
        let keys = &self.keys;
        let t = t.clamp(keys[0].t, keys[keys.len() - 1].t);
        let k = keys.partition_point(|key| key.t <= t).clamp(1, keys.len()) - 1;
        if k + 1 >= keys.len() {
            return (keys[k].position, keys[k].target);
        }
        let (a, b) = (&keys[k], &keys[k + 1]);
        let h = b.t - a.t;
        let s = (t - a.t) / h;
        let tangent = |i: usize, f: fn(&Key) -> DVec3| {
            let (lo, hi) = (i.saturating_sub(1), (i + 1).min(keys.len() - 1));
            (f(&keys[hi]) - f(&keys[lo])) / (keys[hi].t - keys[lo].t) * h
        };
        let hermite = |f: fn(&Key) -> DVec3| {
            let (p0, p1) = (f(a), f(b));
            let (m0, m1) = (tangent(k, f), tangent(k + 1, f));
            let (s2, s3) = (s * s, s * s * s);
            p0 * (2.0 * s3 - 3.0 * s2 + 1.0)
                + m0 * (s3 - 2.0 * s2 + s)
                + p1 * (-2.0 * s3 + 3.0 * s2)
                + m1 * (s3 - s2)
        };
        (hermite(|k| k.position), hermite(|k| k.target))
    }

    /// The bank at `t` seconds, radians: linear between keys, held before the first and after
    /// the last.
    pub fn roll_at(&self, t: f64) -> f64 {
        let keys = &self.keys;
        let t = t.clamp(keys[0].t, keys[keys.len() - 1].t);
        let k = keys.partition_point(|key| key.t <= t).clamp(1, keys.len()) - 1;
        match keys.get(k + 1) {
            Some(b) => {
                let a = &keys[k];
                a.roll + (b.roll - a.roll) * (t - a.t) / (b.t - a.t)
            }
            None => keys[k].roll,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame() -> TerrainFrame {
        TerrainFrame {
            tiles_x: 16,
            tiles_y: 8,
            tile_size: 65,
            spacing: 10.0,
            quantum: 0.0625,
            heights: (0.0, 1000.0),
            origin: DVec3::ZERO,
            // 16 x 8 tiles of 64 cells padded around 700 x 300 samples.
            source_samples: (700, 300),
            archive_origin: (0.0, 0.0),
        }
    }

    #[test]
    fn paths_pass_through_their_keys_and_clamp_outside() {
        for which in [Builtin::Overview, Builtin::Diagonal, Builtin::Low] {
            let f = Flight::builtin(which, &frame());
            assert_eq!(f.duration(), 60.0);
            for key in &f.keys {
                let (p, t) = f.at(key.t);
                assert!((p - key.position).length() < 1e-6, "{which:?}");
                assert!((t - key.target).length() < 1e-6, "{which:?}");
            }
            assert_eq!(f.at(-5.0), f.at(0.0));
            assert_eq!(f.at(1e9), f.at(60.0));
        }
    }

    #[test]
    fn motion_is_continuous() {
        let f = Flight::builtin(Builtin::Diagonal, &frame());
        let mut last = f.at(0.0).0;
        let mut t = 0.0;
        while t < 60.0 {
            t += 0.05;
            let p = f.at(t).0;
            assert!((p - last).length() < 20.0, "jump at {t}");
            last = p;
        }
    }

    #[test]
    fn builtins_stay_over_the_model_and_off_its_padding() {
        let (w, d) = frame().source_extent();
        for which in [Builtin::Overview, Builtin::Diagonal, Builtin::Low] {
            let f = Flight::builtin(which, &frame());
            for k in 0..=600 {
                let p = f.at(k as f64 * 0.1).0;
                assert!(
                    p.x >= 0.0 && p.x <= w && p.z >= 0.0 && p.z <= d,
                    "{which:?} {p}"
                );
            }
        }
    }
}
