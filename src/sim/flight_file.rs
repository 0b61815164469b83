//! Flights read from TOML files.
//!
//! The format (metres in the terrain frame: x east from the north-west corner, y up, z south):
//!
//! ```toml
//! name = "along the ridge"
//! above_ground = false   # true: y values are metres above the ground under the eye
//! [[key]]
//! t = 0.0                # seconds
//! position = [1000.0, 2500.0, 1000.0]
//! look_at = [20000.0, 0.0, 20000.0]
//! roll = 15.0            # degrees banking right (optional, 0 by default)
//! [[key]]
//! t = 30.0
//! position = [40000.0, 1800.0, 30000.0]
//! look_at = [60000.0, 0.0, 50000.0]
//! ```

use std::path::Path;

use glam::DVec3;
use serde::Deserialize;

use crate::engine::terrain::TerrainFrame;
use crate::error::{Error, Result};
use crate::named::Named;
use crate::sim::flight::{Builtin, Flight, Key};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FlightFile {
    name: Option<String>,
    #[serde(default)]
    above_ground: bool,
    key: Vec<KeyFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct KeyFile {
    t: f64,
    position: [f64; 3],
    look_at: [f64; 3],
    /// Degrees, positive banking right.
    #[serde(default)]
    roll: f64,
}

impl Flight {
    /// Reads a TOML flight file (format in the module documentation).
    pub fn from_toml(path: &Path) -> Result<Flight> {
        let name = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(&name, e))?;
        let file: FlightFile =
            toml::from_str(&text).map_err(|e| Error::invalid(&name, e.to_string()))?;
        let keys = file
            .key
            .iter()
            .map(|k| Key {
                t: k.t,
                position: DVec3::from_array(k.position),
                target: DVec3::from_array(k.look_at),
                roll: k.roll.to_radians(),
            })
            .collect();
        let label = file.name.unwrap_or_else(|| name.clone());
        Flight::new(&label, file.above_ground, keys).map_err(|p| Error::invalid(&name, p))
    }

    /// The built-in flight called `name` scaled to the terrain, or else the TOML flight file at
    /// the path `name`.
    pub fn builtin_or_file(name: &str, terrain: &TerrainFrame) -> Result<Flight> {
        match Builtin::from_name(name) {
            Ok(which) => Ok(Flight::builtin(which, terrain)),
            Err(_) => Flight::from_toml(Path::new(name)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn toml_files_load_and_bad_ones_name_the_problem() {
        let dir = tempfile::tempdir().unwrap();
        let good = dir.path().join("good.toml");
        std::fs::write(
            &good,
            "name = \"two keys\"\n[[key]]\nt = 0.0\nposition = [0.0, 100.0, 0.0]\n\
             look_at = [50.0, 0.0, 50.0]\n[[key]]\nt = 10.0\nposition = [100.0, 100.0, 0.0]\n\
             look_at = [150.0, 0.0, 50.0]\nroll = 30.0\n",
        )
        .unwrap();
        let f = Flight::from_toml(&good).unwrap();
        assert_eq!(f.name, "two keys");
        assert_eq!(f.duration(), 10.0);
        let mid = f.at(5.0).0;
        assert!((mid - DVec3::new(50.0, 100.0, 0.0)).length() < 1e-9);
        // Level at the first key, 30° right at the second, 15° between.
        assert_eq!(f.roll_at(-1.0), 0.0);
        assert!((f.roll_at(5.0) - 15f64.to_radians()).abs() < 1e-12);
        assert!((f.roll_at(20.0) - 30f64.to_radians()).abs() < 1e-12);

        let bad = dir.path().join("bad.toml");
        std::fs::write(
            &bad,
            "[[key]]\nt = 1.0\nposition = [0.0, 1.0, 0.0]\nlook_at = [1.0, 0.0, 0.0]\n\
             [[key]]\nt = 1.0\nposition = [0.0, 1.0, 0.0]\nlook_at = [1.0, 0.0, 0.0]\n",
        )
        .unwrap();
        let err = Flight::from_toml(&bad).unwrap_err().to_string();
        assert!(
            err.contains("bad.toml") && err.contains("not later"),
            "{err}"
        );
        std::fs::write(&bad, "[[key]]\nt = \"soon\"\n").unwrap();
        let err = Flight::from_toml(&bad).unwrap_err().to_string();
        assert!(err.contains("bad.toml"), "{err}");
        let missing = Flight::from_toml(&dir.path().join("none.toml")).unwrap_err();
        assert!(missing.to_string().contains("none.toml"));
    }
}
