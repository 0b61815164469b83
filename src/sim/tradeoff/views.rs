//! The views the report renders: a fixed set that every archive gets, scaled to its extent and
//! heights, plus views sampled evenly along a flight.

use glam::DVec3;

use crate::engine::terrain::TerrainFrame;
use crate::sim::flight::Flight;

/// One view: an eye and a point looked at, terrain-frame metres.
#[derive(Clone, Debug, PartialEq)]
pub struct Viewpoint {
    /// Name in tables and file names.
    pub name: String,
    /// Eye position.
    pub eye: DVec3,
    /// Point looked at.
    pub target: DVec3,
    /// Heights count from the ground under the eye.
    pub above_ground: bool,
}

/// The built-in views: high overview, the paper's oblique flyover, low and grazing, towards the
/// horizon (far depth precision), and straight down (texture magnification).
pub fn builtin(terrain: &TerrainFrame) -> Vec<Viewpoint> {
    let (w, d) = terrain.extent();
    let (_, top) = terrain.heights;
    let size = w.max(d);
    let at = |fx: f64, y: f64, fz: f64| DVec3::new(fx * w, y, fz * d);
    let view = |name: &str, eye, target, above_ground| Viewpoint {
        name: name.into(),
        eye,
        target,
        above_ground,
    };
    vec![
        view(
            "overview",
            at(0.5, top + 0.3 * size, 1.0),
            at(0.5, 0.0, 0.45),
            false,
        ),
        view(
            "oblique",
            at(0.25, 0.6 * top + 0.02 * size, 0.25),
            at(0.33, 0.0, 0.33),
            false,
        ),
        view("low", at(0.5, 0.004 * size, 0.3), at(0.5, 0.0, 0.6), true),
        view(
            "horizon",
            at(0.1, top + 0.01 * size, 0.9),
            at(0.9, top, 0.1),
            false,
        ),
        view(
            "down",
            at(0.55, top + 0.05 * size, 0.55),
            at(0.56, 0.0, 0.55),
            false,
        ),
    ]
}

/// `count` views at even times along `flight`, first and last key included.
pub fn from_flight(flight: &Flight, count: usize) -> Vec<Viewpoint> {
    (0..count)
        .map(|k| {
            let t = if count > 1 {
                flight.duration() * k as f64 / (count - 1) as f64
            } else {
                0.0
            };
            let (eye, target) = flight.at(t);
            Viewpoint {
                name: format!("{}@{t:.0}s", flight.name),
                eye,
                target,
                above_ground: flight.above_ground,
            }
        })
        .collect()
}
