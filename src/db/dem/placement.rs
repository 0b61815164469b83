//! Where a grid lies in its own coordinate reference system, and how that becomes metres.
//!
//! A reader that knows its georeferencing describes it as a [`Placement`] in the file's own
//! units (degrees, metres, feet); [`Placement::apply`] turns it into the spacing and origin in
//! metres the build uses, and a mosaic lines its files up by their placements.

use serde::Serialize;

use super::DemInfo;
use super::geographic::Geographic;

/// How a CRS's coordinates become ground metres.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub enum Units {
    /// Longitude and latitude in degrees.
    Degrees,
    /// A projected CRS whose unit is this many metres (1 for metres, 0.3048 for feet).
    Linear(f64),
    /// Web Mercator in units of this many metres: its metres are ground metres over the cosine
    /// of the latitude.
    WebMercator(f64),
}

/// A grid's georeferencing in its own CRS.
#[derive(Clone, Debug, PartialEq)]
pub struct Placement {
    /// The CRS as the file names it (`EPSG:4326`, or its name when it has no code).
    pub crs: String,
    /// Whether the file names its CRS (an EPSG code, GeoKeys, a WKT text): a grid placed by
    /// a corner alone (an `.asc` without `.prj`, a VRT without `SRS`, a GeoTIFF without
    /// GeoKeys) has coordinates in no known CRS, and its archive stores no georeferencing.
    pub named: bool,
    /// How its coordinates become metres.
    pub units: Units,
    /// Cell size east-west and north-south, in the CRS's units.
    pub cell: (f64, f64),
    /// CRS coordinates (x east, y north) of the centre of sample (0, 0), the north-west one.
    pub first: (f64, f64),
}

/// Metres per international foot.
pub(crate) const FOOT: f64 = 0.3048;

/// Metres per US survey foot (the state plane systems' foot).
pub(crate) const US_SURVEY_FOOT: f64 = 1200.0 / 3937.0;

/// The EPSG codes of Web Mercator.
pub(crate) const WEB_MERCATOR: [u32; 2] = [3857, 3785];

/// The Earth's radius Web Mercator projects with.
const WEB_MERCATOR_RADIUS: f64 = 6_378_137.0;

impl Placement {
    /// CRS coordinates of the centre of sample (`column`, `row`).
    pub fn at(&self, column: f64, row: f64) -> (f64, f64) {
        (
            self.first.0 + column * self.cell.0,
            self.first.1 - row * self.cell.1,
        )
    }

    /// Sets `info`'s spacing, east-west scale and origin in metres, notes how, and keeps the
    /// placement in `info`; a grid in degrees that cannot be on Earth sets its spacing problem
    /// instead.
    pub fn apply(&self, info: &mut DemInfo) {
        let (cell_x, cell_y) = self.cell;
        match self.units {
            Units::Degrees => {
                let grid = Geographic {
                    cell_x,
                    cell_y,
                    west: self.first.0,
                    north: self.first.1,
                };
                if !grid.is_plausible(info.height) {
                    info.spacing_problem = Some(format!(
                        "a geographic grid ({}) of {cell_x} x {cell_y} degree cells whose first \
                         sample at {:?} is not a plausible place on Earth, so its latitude (and \
                         metres east-west) is unknown; pass --spacing METRES",
                        self.crs, self.first
                    ));
                    return;
                }
                grid.apply(info);
            }
            Units::Linear(to_metres) | Units::WebMercator(to_metres) => {
                let mut factor = to_metres;
                if to_metres != 1.0 {
                    info.notes.push(format!(
                        "{} in {}: spacing and origin converted to metres (x {to_metres:.7})",
                        self.crs,
                        self.unit_name()
                    ));
                }
                if matches!(self.units, Units::WebMercator(_)) {
                    let rows = info.height.saturating_sub(1) as f64;
                    let centre = self.first.1 - cell_y * rows / 2.0;
                    let latitude = (centre * to_metres / WEB_MERCATOR_RADIUS).sinh().atan();
                    factor *= latitude.cos();
                    info.notes.push(format!(
                        "{} (Web Mercator): its metres are {:.3} ground metres at the grid's \
                         latitude ({:.2}°); spacing and origin scaled to ground metres",
                        self.crs,
                        latitude.cos(),
                        latitude.to_degrees()
                    ));
                }
                info.spacing_hint = Some(cell_y * factor).filter(|s| s.is_finite() && *s > 0.0);
                if (cell_x - cell_y).abs() > 1e-9 * cell_y {
                    info.east_west_scale = cell_x / cell_y;
                }
                info.origin_hint = Some((self.first.0 * factor, self.first.1 * factor))
                    .filter(|(x, y)| x.is_finite() && y.is_finite());
            }
        }
        info.placement = Some(self.clone());
    }

    /// The unit of the CRS's coordinates, for messages.
    pub fn unit_name(&self) -> String {
        match self.units {
            Units::Degrees => "degrees".into(),
            Units::Linear(1.0) => "metres".into(),
            Units::Linear(FOOT) => "feet".into(),
            Units::Linear(US_SURVEY_FOOT) => "US survey feet".into(),
            Units::Linear(m) => format!("units of {m} m"),
            Units::WebMercator(_) => "Web Mercator metres".into(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn feet_become_metres_and_oblong_cells_keep_their_aspect() {
        let p = Placement {
            crs: "EPSG:2927".into(),
            named: true,
            units: Units::Linear(0.3048),
            cell: (20.0, 10.0),
            first: (1000.0, 2000.0),
        };
        let mut info = DemInfo::new("x.tif", 4, 4);
        p.apply(&mut info);
        assert!((info.spacing_hint.unwrap() - 3.048).abs() < 1e-12);
        assert_eq!(info.east_west_scale, 2.0);
        assert_eq!(info.origin_hint, Some((304.8, 609.6)));
        assert_eq!(p.at(2.0, 3.0), (1040.0, 1970.0));
        assert_eq!(info.placement, Some(p));
    }

    #[test]
    fn degrees_off_the_earth_ask_for_the_spacing() {
        let p = Placement {
            crs: "EPSG:4326".into(),
            named: true,
            units: Units::Degrees,
            cell: (0.001, 0.001),
            first: (10.0, 95.0),
        };
        let mut info = DemInfo::new("x.tif", 4, 4);
        p.apply(&mut info);
        assert!(info.spacing_problem.is_some());
        assert_eq!(info.placement, None);
    }
}
