//! Where an archive lies on the Earth, and where a latitude and longitude lie on it.
//!
//! A build from a georeferenced DEM stores a [`Georef`] in the archive: the CRS as the DEM named
//! it and the CRS coordinates of the archive's samples. [`Georef::sample_at`] turns a latitude
//! and longitude into a (fractional) sample of the archive for the CRSs it projects: geographic
//! WGS 84, NAD83 and ETRS89 degrees, UTM on those datums, and Web Mercator. The archive's own
//! coordinates follow from its spacing and origin ([`crate::db::archive::Header::locate`]).
//!
//! Latitudes and longitudes are taken on the archive's datum: a GPS's WGS 84 position on a
//! NAD83 model lands within the datums' difference (a metre or two in North America).

pub mod transverse_mercator;

use serde::Serialize;

use crate::db::dem::Units;
use transverse_mercator::{Ellipsoid, GRS80, TransverseMercator, WGS84};

/// An archive's georeferencing: its CRS and where its samples lie in it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Georef {
    /// The CRS as the DEM named it: `EPSG:32610`, or a quoted name when it has no code.
    pub crs: String,
    /// How the CRS's coordinates become metres.
    pub units: Units,
    /// CRS coordinates (x east, y north) of the archive's sample (0, 0), the north-west one.
    pub first: (f64, f64),
    /// CRS units between the archive's columns (east) and rows (south). Columns a build
    /// resampled to square cells are that much closer than the DEM's.
    pub cell: (f64, f64),
}

/// A latitude and longitude on an archive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SampleAt {
    /// Columns east of sample (0, 0), fractional.
    pub column: f64,
    /// Rows south of sample (0, 0), fractional.
    pub row: f64,
    /// The bearing of the archive's north (its columns' direction) clockwise from true north,
    /// radians: a true heading less this is the heading on the archive's grid.
    pub convergence: f64,
}

/// How latitude and longitude become CRS coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Projection {
    /// Longitude and latitude themselves.
    Geographic,
    /// Universal transverse Mercator.
    Utm {
        tm: TransverseMercator,
        /// The zone's central meridian, degrees.
        meridian: f64,
        /// Metres added to northings: 10 000 km south of the equator.
        false_northing: f64,
    },
    /// Spherical Mercator on WGS 84's semi-major axis, in units of this many metres.
    WebMercator(f64),
}

/// What [`Georef::sample_at`] can project, for messages.
pub const SUPPORTED: &str = "geographic WGS 84, NAD83 or ETRS89 degrees (EPSG:4326, 4269, \
                             4258), UTM in metres on WGS 84 (EPSG:32601-32660, 32701-32760), NAD83 \
                             (EPSG:26901-26923) or ETRS89 (EPSG:25828-25838), and Web Mercator \
                             (EPSG:3857)";

/// The farthest from a UTM zone's central meridian a longitude is projected, degrees: far
/// beyond any model in the zone, well within the series' accuracy.
const MAX_FROM_MERIDIAN: f64 = 30.0;

impl Georef {
    /// The EPSG code of the CRS, when it was named by one.
    pub fn epsg(&self) -> Option<u32> {
        self.crs.strip_prefix("EPSG:")?.parse().ok()
    }

    /// CRS coordinates of archive sample (`column`, `row`).
    pub fn map_at(&self, column: f64, row: f64) -> (f64, f64) {
        (
            self.first.0 + column * self.cell.0,
            self.first.1 - row * self.cell.1,
        )
    }

    /// The unit of the CRS's coordinates, for messages.
    pub fn unit_name(&self) -> &'static str {
        match self.units {
            Units::Degrees => "degrees",
            Units::Linear(_) => "CRS units",
            Units::WebMercator(_) => "Web Mercator units",
        }
    }

    /// Whether latitudes and longitudes can be placed in this CRS: what is supported when
    /// they cannot.
    pub fn projects(&self) -> Result<(), String> {
        self.projection().map(|_| ())
    }

    fn projection(&self) -> Result<Projection, String> {
        let unsupported = || {
            format!(
                "latitude and longitude cannot be placed on {} ({}): supported are {SUPPORTED}",
                self.crs,
                match self.units {
                    Units::Degrees => "degrees".to_string(),
                    Units::Linear(m) | Units::WebMercator(m) => format!("units of {m} m"),
                }
            )
        };
        let code = self.epsg();
        let named = |names: &[&str]| {
            let crs = self.crs.to_ascii_uppercase().replace(' ', "");
            names.iter().any(|n| crs.contains(n))
        };
        match self.units {
            Units::Degrees
                if code.map_or(named(&["WGS84", "NAD83", "ETRS89"]), |c| {
                    [4326, 4269, 4258].contains(&c)
                }) =>
            {
                Ok(Projection::Geographic)
            }
            Units::Linear(1.0) => {
                let (ellipsoid, zone, south): (Ellipsoid, u32, bool) = match code {
                    Some(c @ 32601..=32660) => (WGS84, c - 32600, false),
                    Some(c @ 32701..=32760) => (WGS84, c - 32700, true),
                    Some(c @ 26901..=26923) => (GRS80, c - 26900, false),
                    Some(c @ 25828..=25838) => (GRS80, c - 25800, false),
                    _ => return Err(unsupported()),
                };
                Ok(Projection::Utm {
                    tm: TransverseMercator::new(ellipsoid, 0.9996),
                    meridian: f64::from(zone) * 6.0 - 183.0,
                    false_northing: if south { 10_000_000.0 } else { 0.0 },
                })
            }
            Units::WebMercator(metres) => Ok(Projection::WebMercator(metres)),
            _ => Err(unsupported()),
        }
    }

    /// Where latitude `latitude` and longitude `longitude` (degrees, on the archive's datum)
    /// lie among the archive's samples, or why they cannot be placed.
    pub fn sample_at(&self, latitude: f64, longitude: f64) -> Result<SampleAt, String> {
        if !(latitude.is_finite() && longitude.is_finite())
            || latitude.abs() > 90.0
            || longitude.abs() > 360.0
        {
            return Err(format!(
                "latitude {latitude}, longitude {longitude} is not a place on Earth"
            ));
        }
        let ((x, y), convergence) = match self.projection()? {
            Projection::Geographic => {
                // The longitude, a whole number of turns away, nearest the grid's west edge.
                let turns = ((self.first.0 - longitude) / 360.0).round();
                ((longitude + 360.0 * turns, latitude), 0.0)
            }
            Projection::Utm {
                tm,
                meridian,
                false_northing,
            } => {
                let from = (longitude - meridian + 540.0).rem_euclid(360.0) - 180.0;
                if from.abs() > MAX_FROM_MERIDIAN || latitude.abs() >= 90.0 {
                    return Err(format!(
                        "latitude {latitude}, longitude {longitude} is {:.1} degrees from the \
                         central meridian {meridian} of {}: farther than {MAX_FROM_MERIDIAN}",
                        from.abs(),
                        self.crs
                    ));
                }
                let p = tm.forward(latitude.to_radians(), from.to_radians());
                ((500_000.0 + p.x, false_northing + p.y), p.convergence)
            }
            Projection::WebMercator(metres) => {
                let limit = 85.051_128_78;
                if latitude.abs() > limit {
                    return Err(format!(
                        "latitude {latitude} is beyond Web Mercator's ±{limit} degrees"
                    ));
                }
                let r = WGS84.a / metres;
                let phi = latitude.to_radians();
                let lambda = (longitude + 540.0).rem_euclid(360.0) - 180.0;
                let y = r * (std::f64::consts::FRAC_PI_4 + phi / 2.0).tan().ln();
                ((r * lambda.to_radians(), y), 0.0)
            }
        };
        Ok(SampleAt {
            column: (x - self.first.0) / self.cell.0,
            row: (self.first.1 - y) / self.cell.1,
            convergence,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn utm(code: u32) -> Georef {
        Georef {
            crs: format!("EPSG:{code}"),
            units: Units::Linear(1.0),
            first: (500_000.0, 5_000_000.0),
            cell: (10.0, 10.0),
        }
    }

    #[test]
    fn a_geographic_grid_is_counted_in_its_cells() {
        let g = Georef {
            crs: "EPSG:4326".into(),
            units: Units::Degrees,
            first: (-122.0, 47.0),
            cell: (0.25, 0.125),
        };
        let s = g.sample_at(46.5, -121.0).unwrap();
        assert_eq!((s.column, s.row, s.convergence), (4.0, 4.0, 0.0));
        // A longitude a turn away is the same place.
        assert_eq!(g.sample_at(46.5, 239.0).unwrap(), s);
        assert_eq!(g.map_at(4.0, 4.0), (-121.0, 46.5));
    }

    #[test]
    fn utm_zones_of_both_hemispheres_and_datums() {
        // On the central meridian of zone 10 (123 W) at the equator: easting 500 km,
        // northing 0 (north) or 10 000 km (south).
        let north = utm(32610).sample_at(0.0, -123.0).unwrap();
        assert_eq!((north.column, north.row), (0.0, 500_000.0));
        let south = Georef {
            first: (500_000.0, 10_000_000.0),
            ..utm(32710)
        };
        let s = south.sample_at(0.0, -123.0).unwrap();
        assert_eq!((s.column, s.row), (0.0, 0.0));
        // East of the meridian in the north, grid north lies east of true north.
        assert!(utm(26910).sample_at(47.0, -122.0).unwrap().convergence > 0.0);
        let far = utm(32610).sample_at(47.0, 120.0).unwrap_err();
        assert!(
            far.contains("central meridian -123") && far.contains("EPSG:32610"),
            "{far}"
        );
    }

    #[test]
    fn web_mercator_is_the_sphere_of_wgs84s_axis() {
        let g = Georef {
            crs: "EPSG:3857".into(),
            units: Units::WebMercator(1.0),
            first: (0.0, 0.0),
            cell: (1.0, 1.0),
        };
        // 180 degrees east is half the equator of the 6 378 137 m sphere.
        let s = g.sample_at(0.0, 180.0 - 1e-12).unwrap();
        assert!(
            (s.column - 20_037_508.342_789_244).abs() < 1e-4,
            "{}",
            s.column
        );
        // Published: 45 N is 5 621 521.486 m north.
        let s = g.sample_at(45.0, 0.0).unwrap();
        assert!((-s.row - 5_621_521.486_192_066).abs() < 1e-4, "{}", s.row);
        assert!(g.sample_at(86.0, 0.0).is_err());
    }

    #[test]
    fn other_crss_are_refused_naming_them_and_what_is_supported() {
        let state_plane = Georef {
            crs: "EPSG:2927".into(),
            units: Units::Linear(1200.0 / 3937.0),
            ..utm(0)
        };
        let e = state_plane.sample_at(47.0, -122.0).unwrap_err();
        assert!(e.contains("EPSG:2927") && e.contains("UTM"), "{e}");
        let nad27 = Georef {
            crs: "EPSG:4267".into(),
            units: Units::Degrees,
            ..utm(0)
        };
        assert!(
            nad27
                .sample_at(47.0, -122.0)
                .unwrap_err()
                .contains("EPSG:4267")
        );
        assert!(utm(32610).sample_at(f64::NAN, 0.0).is_err());
        assert!(utm(32610).sample_at(91.0, 0.0).is_err());
    }
}
