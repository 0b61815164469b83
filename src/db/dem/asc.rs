//! ESRI ASCII grids (`.asc`): a `key value` header, then rows of numbers.

use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::Path;

use super::geographic::Geographic;
use super::placement::{Placement, Units};
use super::wkt;
use super::{DemInfo, DemReader, check_dimensions};
use crate::error::{Error, Result};

/// Cell sizes below this with no unit given are taken as degrees: no metric grid has samples
/// closer than a centimetre, and 0.01 degree is over a kilometre.
pub const DEGREE_CELL_LIMIT: f64 = 0.01;

/// The longest token (number or header key) accepted, to bound memory on garbage input.
const MAX_TOKEN: usize = 64;

/// Streams rows of an ESRI ASCII grid.
pub struct AscReader {
    info: DemInfo,
    tokens: Tokens<BufReader<File>>,
    nodata: Option<f64>,
    next_row: usize,
}

struct Tokens<R> {
    input: R,
    pending: Option<String>,
}

impl<R: BufRead> Tokens<R> {
    fn next(&mut self, name: &str) -> Result<Option<String>> {
        if let Some(t) = self.pending.take() {
            return Ok(Some(t));
        }
        let mut token = Vec::new();
        loop {
            let buf = self.input.fill_buf().map_err(|e| Error::io(name, e))?;
            if buf.is_empty() {
                break;
            }
            let mut used = 0;
            let mut done = false;
            for &b in buf {
                used += 1;
                if b.is_ascii_whitespace() {
                    if !token.is_empty() {
                        done = true;
                        break;
                    }
                } else {
                    if token.len() == MAX_TOKEN {
                        return Err(Error::invalid(name, "token too long for an ASCII grid"));
                    }
                    token.push(b);
                }
            }
            self.input.consume(used);
            if done {
                break;
            }
        }
        if token.is_empty() {
            return Ok(None);
        }
        String::from_utf8(token)
            .map(Some)
            .map_err(|_| Error::invalid(name, "non-ASCII text in an ASCII grid"))
    }
}

impl AscReader {
    /// Opens `path` and parses the header.
    pub fn open(path: &Path) -> Result<Self> {
        let name = path.display().to_string();
        let file = File::open(path).map_err(|e| Error::io(&name, e))?;
        let mut tokens = Tokens {
            input: BufReader::new(file),
            pending: None,
        };
        let header = Header::read(&mut tokens, &name)?;
        let width = dimension(header.ncols, "ncols", &name)?;
        let height = dimension(header.nrows, "nrows", &name)?;
        check_dimensions(&name, width, height)?;
        let file_len = tokens
            .input
            .get_ref()
            .metadata()
            .map_err(|e| Error::io(&name, e))?
            .len();
        check_file_holds(&name, width, height, file_len)?;
        let mut info = DemInfo::new(&name, width, height);
        let cell = header.cell.filter(|c| c.is_finite() && *c > 0.0);
        let origin_hint = cell.and_then(|c| header.north_west(c, height));
        if let Some((x, y)) = origin_hint
            && !(x.is_finite() && y.is_finite())
        {
            return Err(Error::invalid(
                &name,
                format!("its first sample lies at ({x}, {y}): the corner is not a finite number"),
            ));
        }
        let prj = sidecar_crs(path, &mut info);
        match (cell, origin_hint, prj) {
            (Some(c), Some(first), Some((crs, units))) => Placement {
                crs,
                named: true,
                units,
                cell: (c, c),
                first,
            }
            .apply(&mut info),
            (Some(c), _, _) if c < DEGREE_CELL_LIMIT => in_degrees(&mut info, c, origin_hint),
            (Some(c), Some(first), None) => Placement {
                crs: NO_CRS.into(),
                named: false,
                units: Units::Linear(1.0),
                cell: (c, c),
                first,
            }
            .apply(&mut info),
            _ => info.spacing_hint = cell,
        }
        Ok(AscReader {
            info,
            tokens,
            nodata: header.nodata,
            next_row: 0,
        })
    }
}

/// The `key value` lines before the first sample.
#[derive(Default)]
struct Header {
    ncols: Option<f64>,
    nrows: Option<f64>,
    cell: Option<f64>,
    nodata: Option<f64>,
    xll: Option<f64>,
    yll: Option<f64>,
    /// Whether `xll`/`yll` came from `xllcenter`/`yllcenter` (the lower-left sample's centre)
    /// rather than the `corner` keys (its outer corner).
    centre: [bool; 2],
}

impl Header {
    /// Reads keys until the first number, which is left pending as the first sample.
    fn read<R: BufRead>(tokens: &mut Tokens<R>, name: &str) -> Result<Self> {
        let mut header = Header::default();
        while let Some(key) = tokens.next(name)? {
            if key.parse::<f64>().is_ok() {
                tokens.pending = Some(key);
                break;
            }
            let value = tokens
                .next(name)?
                .ok_or_else(|| Error::invalid(name, format!("header key {key} has no value")))?;
            let number: f64 = value.parse().map_err(|_| {
                Error::invalid(
                    name,
                    format!("header {key} has a non-numeric value {value:?}"),
                )
            })?;
            header.set(&key, number, name)?;
        }
        Ok(header)
    }

    fn set(&mut self, key: &str, number: f64, name: &str) -> Result<()> {
        match key.to_ascii_lowercase().as_str() {
            "ncols" => self.ncols = Some(number),
            "nrows" => self.nrows = Some(number),
            "cellsize" | "dx" | "dy" => self.cell = Some(number),
            "xllcorner" => (self.xll, self.centre[0]) = (Some(number), false),
            "yllcorner" => (self.yll, self.centre[1]) = (Some(number), false),
            "xllcenter" => (self.xll, self.centre[0]) = (Some(number), true),
            "yllcenter" => (self.yll, self.centre[1]) = (Some(number), true),
            "nodata_value" => self.nodata = Some(number),
            _ => {
                return Err(Error::invalid(
                    name,
                    format!("unknown ASCII grid header key {key:?}"),
                ));
            }
        }
        Ok(())
    }

    /// The centre of the first (north-west) sample, when the header places the grid.
    fn north_west(&self, cell: f64, height: usize) -> Option<(f64, f64)> {
        let (x, y) = (self.xll?, self.yll?);
        let half = self.centre.map(|c| if c { 0.0 } else { cell / 2.0 });
        Some((x + half[0], y + half[1] + (height - 1) as f64 * cell))
    }
}

/// A header count: a positive integer below a billion.
fn dimension(value: Option<f64>, key: &str, name: &str) -> Result<usize> {
    match value {
        Some(n) if n >= 1.0 && n.fract() == 0.0 && n < 1e9 => Ok(n as usize),
        Some(n) => Err(Error::invalid(
            name,
            format!("{key} {n} is not a positive integer"),
        )),
        None => Err(Error::invalid(name, format!("the header has no {key}"))),
    }
}

/// Every sample takes at least a digit and a separator: a header claiming more samples than the
/// file can hold is refused before anything is allocated or written.
fn check_file_holds(name: &str, width: usize, height: usize, file_len: u64) -> Result<()> {
    let least = (width as u64 * height as u64).saturating_mul(2) - 1;
    if least > file_len {
        return Err(Error::invalid(
            name,
            format!(
                "the header claims {width} x {height} samples, which take at least \
                 {least} bytes, but the file has {file_len}"
            ),
        ));
    }
    Ok(())
}

/// The CRS of the `.prj` file beside `path` (its WKT, as GDAL and ArcGIS write it), when there
/// is one; one that cannot be read is noted in `info` and ignored.
fn sidecar_crs(path: &Path, info: &mut DemInfo) -> Option<(String, Units)> {
    let prj = path.with_extension("prj");
    let text = std::fs::read(&prj).ok()?;
    if text.len() > 1 << 20 {
        info.notes
            .push(format!("{} is over 1 MiB: ignored", prj.display()));
        return None;
    }
    match wkt::crs(&String::from_utf8_lossy(&text)) {
        Ok(crs) => Some(crs),
        Err(e) => {
            info.notes
                .push(format!("{} unreadable ({e}): ignored", prj.display()));
            None
        }
    }
}

/// What an ASCII grid's CRS is called when no `.prj` file names it.
const NO_CRS: &str = "no CRS (no .prj file beside the grid names one)";

/// Describes a grid whose cell size `cell` is small enough to be degrees: geographic when the
/// header places it on Earth (`north_west`, the centre of its first sample), else a grid whose
/// spacing the user must give.
fn in_degrees(info: &mut DemInfo, cell: f64, north_west: Option<(f64, f64)>) {
    let grid = north_west.map(|(west, north)| Geographic {
        cell_x: cell,
        cell_y: cell,
        west,
        north,
    });
    match grid.filter(|g| g.is_plausible(info.height)) {
        Some(g) => {
            let placement = Placement {
                crs: NO_CRS.into(),
                named: false,
                units: Units::Degrees,
                cell: (cell, cell),
                first: (g.west, g.north),
            };
            info.notes.push(format!(
                "cell size {cell} is below {DEGREE_CELL_LIMIT} and an ASCII grid gives no \
                 unit: taken as degrees, placed by the header's corner; pass --spacing METRES \
                 if the cells are metres"
            ));
            placement.apply(info);
        }
        None => {
            info.spacing_problem = Some(format!(
                "cell size {cell} is below {DEGREE_CELL_LIMIT}: almost certainly degrees, but the \
                 header gives no corner on Earth to tell the latitude; pass --spacing METRES"
            ));
        }
    }
}

impl DemReader for AscReader {
    fn info(&self) -> &DemInfo {
        &self.info
    }

    fn read_row(&mut self, row: &mut [f32]) -> Result<()> {
        let name = &self.info.name;
        for (i, v) in row.iter_mut().enumerate() {
            let t = self.tokens.next(name)?.ok_or_else(|| {
                Error::invalid(
                    name,
                    format!(
                        "the grid ends at row {}, column {i} of {} x {}",
                        self.next_row, self.info.width, self.info.height
                    ),
                )
            })?;
            let x: f64 = t.parse().map_err(|_| {
                Error::invalid(
                    name,
                    format!("row {}, column {i}: {t:?} is not a number", self.next_row),
                )
            })?;
            *v = if Some(x) == self.nodata {
                f32::NAN
            } else {
                x as f32
            };
        }
        self.next_row += 1;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header(text: &str) -> Header {
        let mut tokens = Tokens {
            input: text.as_bytes(),
            pending: None,
        };
        Header::read(&mut tokens, "test.asc").unwrap()
    }

    #[test]
    fn corner_and_centre_keys_place_the_first_sample_per_axis() {
        let corners = header("ncols 3 nrows 2 xllcorner 100 yllcorner 200 cellsize 10 1");
        assert_eq!(corners.north_west(10.0, 2), Some((105.0, 215.0)));
        let centres = header("ncols 3 nrows 2 xllcenter 100 yllcenter 200 cellsize 10 1");
        assert_eq!(centres.north_west(10.0, 2), Some((100.0, 210.0)));
        let mixed = header("ncols 3 nrows 2 xllcorner 100 yllcenter 200 cellsize 10 1");
        assert_eq!(mixed.north_west(10.0, 2), Some((105.0, 210.0)));
        assert_eq!(
            header("ncols 3 nrows 2 cellsize 10 1").north_west(10.0, 2),
            None
        );
    }
}
