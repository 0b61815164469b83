//! Latitudes and longitudes on an archive: its georeferencing ([`crate::db::georef`]) and its
//! own coordinates (spacing and origin) together.

use super::Header;
use crate::db::georef::Georef;
use crate::error::{Error, Result};

/// A latitude and longitude placed on an archive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Located {
    /// The archive's own east coordinate (that of [`Header::origin_x`]), metres.
    pub east: f64,
    /// The archive's own north coordinate (that of [`Header::origin_y`]), metres.
    pub north: f64,
    /// The bearing of the archive's north clockwise from true north, radians (UTM's grid
    /// convergence; 0 for geographic and Web Mercator archives): a true heading less this is
    /// the heading on the archive.
    pub convergence: f64,
}

impl Header {
    /// Where latitude `latitude` and longitude `longitude` (degrees, on the archive's datum)
    /// lie in the archive's own coordinates; an error naming `name` (the archive) when it has
    /// no georeferencing or a CRS that latitudes cannot be placed on. Heights need nothing:
    /// the archive's are metres above the vertical datum of the DEM it was built from.
    pub fn locate(&self, latitude: f64, longitude: f64, name: &str) -> Result<Located> {
        let at = self
            .placing(name)?
            .sample_at(latitude, longitude)
            .map_err(|p| Error::invalid(name, p))?;
        Ok(Located {
            east: self.origin_x + at.column * self.spacing,
            north: self.origin_y - at.row * self.spacing,
            convergence: at.convergence,
        })
    }

    /// The georeferencing that places latitudes and longitudes on the archive `name`, or why
    /// it has none: no georeferencing, or a CRS not supported.
    pub fn placing(&self, name: &str) -> Result<&Georef> {
        let georef = self.georef.as_ref().ok_or_else(|| {
            Error::invalid(
                name,
                "has no georeferencing (its DEM named no CRS, or it was built by an older \
                 stripmask), so a latitude and longitude cannot be placed on it; poses in its \
                 own coordinates can",
            )
        })?;
        georef.projects().map_err(|p| Error::invalid(name, p))?;
        Ok(georef)
    }

    /// CRS coordinates of the model's corner samples, north-west, north-east, south-west and
    /// south-east, when the archive is georeferenced.
    pub fn corners(&self) -> Option<[(f64, f64); 4]> {
        let g = self.georef.as_ref()?;
        let (e, s) = (
            f64::from(self.source_width.saturating_sub(1)),
            f64::from(self.source_height.saturating_sub(1)),
        );
        Some([
            g.map_at(0.0, 0.0),
            g.map_at(e, 0.0),
            g.map_at(0.0, s),
            g.map_at(e, s),
        ])
    }
}
