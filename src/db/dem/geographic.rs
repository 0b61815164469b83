//! Grids in degrees of longitude and latitude: metres on both axes.
//!
//! A degree of latitude is [`METRES_PER_DEGREE`] metres everywhere; a degree of longitude is that
//! times the cosine of the latitude. The grid is placed on an equirectangular projection at the
//! latitude of its centre: north-south spacing `cell_y * METRES_PER_DEGREE`, east-west spacing
//! `cell_x * METRES_PER_DEGREE * cos(centre)`, and the origin is the north-west sample's
//! longitude and latitude in the same metres. Over one model (a few degrees at most) distances
//! are true to well under 1%.

use super::{DemInfo, METRES_PER_DEGREE};

/// Where a geographic grid lies and how large its cells are, in degrees.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Geographic {
    /// Degrees of longitude between columns.
    pub cell_x: f64,
    /// Degrees of latitude between rows.
    pub cell_y: f64,
    /// Longitude of the north-west sample (its centre).
    pub west: f64,
    /// Latitude of the north-west sample (its centre).
    pub north: f64,
}

impl Geographic {
    /// Whether the numbers can be a place on Earth with usable cells (latitude within ±85°,
    /// where a degree of longitude is still over 9 km).
    pub fn is_plausible(&self, height: usize) -> bool {
        let south = self.north - (height.max(1) - 1) as f64 * self.cell_y;
        let cells = [self.cell_x, self.cell_y];
        cells.iter().all(|c| c.is_finite() && *c > 0.0 && *c < 10.0)
            && self.west.is_finite()
            && (-360.0..=360.0).contains(&self.west)
            && (-85.0..=85.0).contains(&self.north)
            && (-85.0..=85.0).contains(&south)
    }

    /// Latitude of the grid's centre for a grid of `height` rows.
    pub fn centre_latitude(&self, height: usize) -> f64 {
        self.north - (height.max(1) - 1) as f64 * self.cell_y / 2.0
    }

    /// Sets `info`'s spacing, east-west scale and origin in metres, and says so in its notes.
    pub fn apply(&self, info: &mut DemInfo) {
        let latitude = self.centre_latitude(info.height);
        let cos = latitude.to_radians().cos();
        let north_south = self.cell_y * METRES_PER_DEGREE;
        let east_west = self.cell_x * METRES_PER_DEGREE * cos;
        info.spacing_hint = Some(north_south);
        info.east_west_scale = east_west / north_south;
        info.origin_hint = Some((
            self.west * METRES_PER_DEGREE * cos,
            self.north * METRES_PER_DEGREE,
        ));
        info.notes.push(format!(
            "geographic grid of {:.6}° x {:.6}° cells centred at latitude {latitude:.4}°: \
             {east_west:.3} m east-west x {north_south:.3} m north-south",
            self.cell_x, self.cell_y
        ));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fifty_degrees_north_shrinks_east_west_by_its_cosine() {
        let g = Geographic {
            cell_x: 1.0 / 3600.0,
            cell_y: 1.0 / 3600.0,
            west: 7.0,
            north: 50.5,
        };
        let mut info = DemInfo::new("n50.tif", 3601, 3601);
        assert!(g.is_plausible(3601));
        g.apply(&mut info);
        assert!((info.spacing_hint.unwrap() - 30.922).abs() < 0.01);
        assert!((info.east_west_scale - 50f64.to_radians().cos()).abs() < 1e-9);
        let (x, y) = info.origin_hint.unwrap();
        assert!((y - 50.5 * METRES_PER_DEGREE).abs() < 1e-6);
        assert!((x - 7.0 * METRES_PER_DEGREE * 50f64.to_radians().cos()).abs() < 1e-6);
        assert!(!Geographic { north: 89.0, ..g }.is_plausible(3601));
    }
}
