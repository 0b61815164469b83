//! Cutting a streamed DEM into tiles of `2^n + 1` samples per side with shared borders.
//!
//! Tile `(tx, ty)` covers samples `tx * (s - 1) ..= tx * (s - 1) + s - 1` across and the same
//! down, so neighbours share their border row or column. The grid is padded on the east and
//! south to a whole number of tiles by repeating the last column and row of the DEM.
//!
//! Memory: [`BandReader`] holds one band of `s` rows of the padded width (`f32` metres) and one
//! input row; it never holds more than one row of tiles.

use crate::db::dem::{DemReader, EastWest, FillStats, NodataFill};
use crate::error::{Error, Result};

/// The largest tile side supported (`2^12 + 1`).
pub const MAX_TILE_SIZE: usize = 4097;

/// How a DEM of `width x height` samples is cut into tiles.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tiling {
    /// Samples per tile side, `2^n + 1`.
    pub tile_size: usize,
    /// Tiles across (west to east).
    pub tiles_x: usize,
    /// Tiles down (north to south).
    pub tiles_y: usize,
    /// Samples per row of the source DEM.
    pub width: usize,
    /// Rows of the source DEM.
    pub height: usize,
}

/// Whether `s` is a valid tile size: `2^n + 1` with `n >= 1`, at most [`MAX_TILE_SIZE`].
pub fn is_valid_tile_size(s: usize) -> bool {
    (3..=MAX_TILE_SIZE).contains(&s) && (s - 1).is_power_of_two()
}

impl Tiling {
    /// The tiling of a `width x height` DEM with `tile_size` samples per tile side.
    pub fn new(width: usize, height: usize, tile_size: usize) -> Result<Tiling> {
        if !is_valid_tile_size(tile_size) {
            return Err(Error::setting(
                "tile size",
                tile_size,
                format!("2^n + 1 between 3 and {MAX_TILE_SIZE}"),
            ));
        }
        let step = tile_size - 1;
        Ok(Tiling {
            tile_size,
            tiles_x: (width.max(2) - 1).div_ceil(step),
            tiles_y: (height.max(2) - 1).div_ceil(step),
            width,
            height,
        })
    }

    /// Samples per row after padding: `tiles_x * (s - 1) + 1`.
    pub fn padded_width(&self) -> usize {
        self.tiles_x * (self.tile_size - 1) + 1
    }

    /// Number of tiles.
    pub fn tile_count(&self) -> usize {
        self.tiles_x * self.tiles_y
    }
}

/// One row of tiles: `s` rows of the padded grid, in metres, and for level 0 which samples
/// were nodata in the file.
#[derive(Clone)]
pub struct Band {
    /// Which tile row this is.
    pub tile_row: usize,
    grid: Tiling,
    samples: Vec<f32>,
    /// Per sample, whether it was nodata before the fill (empty when not known: the pyramid's
    /// levels above 0 know absence from their children).
    nodata: Vec<bool>,
}

impl Band {
    /// Band `tile_row` of `grid` with `samples` (`s` rows of the padded width), no nodata known.
    pub fn new(tile_row: usize, grid: Tiling, samples: Vec<f32>) -> Band {
        debug_assert_eq!(samples.len(), grid.padded_width() * grid.tile_size);
        Band {
            tile_row,
            grid,
            samples,
            nodata: Vec::new(),
        }
    }

    /// The tiling this band is a row of.
    pub fn grid(&self) -> Tiling {
        self.grid
    }

    /// Row `j` (`0 ..= s - 1`) of the band, the padded width.
    pub fn row(&self, j: usize) -> &[f32] {
        let w = self.grid.padded_width();
        &self.samples[j * w..(j + 1) * w]
    }

    /// The `s * s` heights of tile column `tx` in this band, row-major.
    pub fn tile_heights(&self, tx: usize) -> Vec<f32> {
        let s = self.grid.tile_size;
        let w = self.grid.padded_width();
        let x0 = tx * (s - 1);
        let mut out = Vec::with_capacity(s * s);
        for j in 0..s {
            out.extend_from_slice(&self.samples[j * w + x0..j * w + x0 + s]);
        }
        out
    }

    /// Whether every sample of tile column `tx` was nodata in the file (false when unknown).
    pub fn tile_is_nodata(&self, tx: usize) -> bool {
        if self.nodata.is_empty() {
            return false;
        }
        let s = self.grid.tile_size;
        let w = self.grid.padded_width();
        let x0 = tx * (s - 1);
        (0..s).all(|j| self.nodata[j * w + x0..j * w + x0 + s].iter().all(|&n| n))
    }

    /// The height of padded-grid column `x`, row `y` of this band, or `None` beyond the grid.
    fn sample(&self, x: isize, y: usize) -> Option<f32> {
        let w = self.grid.padded_width();
        usize::try_from(x)
            .ok()
            .filter(|&x| x < w)
            .map(|x| self.samples[y * w + x])
    }
}

/// A band with the bands north and south of it (`None` at the grid's edges): what the samples
/// just outside its tiles' borders are read from.
pub struct BandWindow<'a> {
    /// The band north of `current`.
    pub north: Option<&'a Band>,
    /// The band whose tiles are encoded.
    pub current: &'a Band,
    /// The band south of `current`.
    pub south: Option<&'a Band>,
}

impl BandWindow<'_> {
    /// The height of the sample `(x, y)` whole-tile steps from the north-west sample of tile
    /// column `tx` of the current band, up to one tile beyond it in every direction; `None`
    /// beyond the grid.
    pub fn around(&self, tx: usize, x: isize, y: isize) -> Option<f32> {
        let step = self.current.grid.tile_size as isize - 1;
        let column = (tx as isize) * step + x;
        let (band, row) = match y {
            y if y < 0 => (self.north?, y + step),
            y if y > step => (self.south?, y - step),
            y => (self.current, y),
        };
        band.sample(column, usize::try_from(row).ok()?)
    }
}

/// Reads a DEM band by band (one row of tiles at a time).
pub struct BandReader<R> {
    reader: NodataFill<R>,
    grid: Tiling,
    vertical_scale: f32,
    columns: Option<EastWest>,
    band: Band,
    rows_read: usize,
    /// One row as read, and resampled when `columns` says.
    row: Vec<f32>,
    resampled: Vec<f32>,
    /// Per sample of `row`, whether it was nodata in the file, and resampled.
    row_nodata: Vec<bool>,
    resampled_nodata: Vec<bool>,
    /// The lowest and highest height read so far, metres.
    range: (f32, f32),
}

impl<R: DemReader> BandReader<R> {
    /// Streams `reader` in bands of `grid.tile_size` rows; heights are scaled by `vertical_scale`,
    /// rows resampled by `columns` (whose output width is `grid.width`) when given.
    pub fn new(
        reader: NodataFill<R>,
        grid: Tiling,
        vertical_scale: f32,
        columns: Option<EastWest>,
    ) -> Self {
        let w = grid.padded_width() * grid.tile_size;
        let band = Band {
            tile_row: 0,
            grid,
            samples: vec![0.0; w],
            nodata: vec![false; w],
        };
        let width = reader.info().width;
        let resampled = if columns.is_some() { grid.width } else { 0 };
        BandReader {
            reader,
            grid,
            vertical_scale,
            columns,
            band,
            rows_read: 0,
            row: vec![0.0; width],
            resampled: vec![0.0; resampled],
            row_nodata: vec![false; width],
            resampled_nodata: vec![false; resampled],
            range: (f32::INFINITY, f32::NEG_INFINITY),
        }
    }

    /// What the nodata fill did to the rows read so far.
    pub fn fill_stats(&self) -> FillStats {
        self.reader.stats()
    }

    /// The lowest and highest height read so far, metres (infinite before the first row).
    pub fn height_range(&self) -> (f32, f32) {
        self.range
    }

    /// The next band, or `None` after the last tile row.
    pub fn next_band(&mut self) -> Result<Option<&Band>> {
        let s = self.grid.tile_size;
        let w = self.grid.padded_width();
        let first = if self.rows_read == 0 {
            0
        } else {
            if self.band.tile_row + 1 >= self.grid.tiles_y {
                return Ok(None);
            }
            self.band.tile_row += 1;
            // The last row of the previous band is the first row of this one.
            self.band.samples.copy_within((s - 1) * w..s * w, 0);
            self.band.nodata.copy_within((s - 1) * w..s * w, 0);
            1
        };
        for j in first..s {
            let dst = j * w;
            if self.rows_read < self.grid.height {
                self.reader
                    .read_row_marking(&mut self.row, Some(&mut self.row_nodata))?;
                self.rows_read += 1;
                let (row, nodata) = match &self.columns {
                    Some(c) => {
                        c.apply(&self.row, &mut self.resampled);
                        c.apply_nodata(&self.row_nodata, &mut self.resampled_nodata);
                        (&self.resampled, &self.resampled_nodata)
                    }
                    None => (&self.row, &self.row_nodata),
                };
                let out = &mut self.band.samples[dst..dst + w];
                for (o, v) in out.iter_mut().zip(row) {
                    *o = v * self.vertical_scale;
                    self.range = (self.range.0.min(*o), self.range.1.max(*o));
                }
                let last = out[self.grid.width - 1];
                out[self.grid.width..].fill(last);
                let marks = &mut self.band.nodata[dst..dst + w];
                marks[..self.grid.width].copy_from_slice(&nodata[..self.grid.width]);
                let last = marks[self.grid.width - 1];
                marks[self.grid.width..].fill(last);
            } else {
                // South padding: repeat the previous row.
                self.band.samples.copy_within(dst - w..dst, dst);
                self.band.nodata.copy_within(dst - w..dst, dst);
            }
        }
        Ok(Some(&self.band))
    }
}
