//! `stripmask build`: stream a DEM band by band, encode each tile, write the archive.
//!
//! Memory held at once: three bands of `s` rows of the padded width (f32) — the band being
//! encoded and its neighbours north and south, which the tiles' aprons
//! ([`crate::db::tile::Apron`]) are read from — one input row, the
//! reader's own strip or tile row, the nodata fill's window of rows
//! ([`crate::db::dem::NodataFill`]), the encoded tiles of one band (they are encoded in
//! parallel, then written in order), and the texture image when one is given.

use std::path::{Path, PathBuf};
use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;

use crate::db::archive::{ArchiveWriter, Codec, Header, MAX_SPACING, compress, partial};
use crate::db::dem::{self, DemInfo, DemReader, EastWest, NodataFill, OpenOptions};
use crate::db::texture_gen::{ImageTexture, shaded};
use crate::db::tile::{Tile, progressive_levels};
use crate::db::tiling::{BandReader, BandWindow, Tiling};
use crate::error::{Error, Result};

/// What `build` makes of a DEM.
#[derive(Clone, Debug, PartialEq)]
pub struct BuildOptions {
    /// Samples per tile side, `2^n + 1`.
    pub tile_size: usize,
    /// Metres between samples; `None` takes the file's own spacing, or 1.
    pub spacing: Option<f64>,
    /// Metres per raw height unit.
    pub vertical_scale: f64,
    /// World position of sample (0, 0); `None` takes the file's own, or (0, 0).
    pub origin: Option<(f64, f64)>,
    /// Texels per grid cell in the tile textures, a power of two.
    pub texture_factor: usize,
    /// A colour image covering the DEM to cut into textures; `None` computes them from heights.
    pub texture_image: Option<PathBuf>,
    /// How tile payloads are stored.
    pub codec: Codec,
    /// Metres per height quantum, shared by all tiles so that neighbours agree on their shared
    /// samples; a tile's relief must fit 65535 quanta (4096 m at the default 1/16 m). `None`:
    /// [`DEFAULT_HEIGHT_QUANTUM`], which [`build_file`] coarsens to a power of two that fits
    /// when a tile's relief needs it.
    pub height_quantum: Option<f32>,
    /// Progressive levels of every tile stored again as the archive's base, the coarse copy of
    /// the whole terrain a client fetches first (0: none).
    pub base_levels: usize,
}

/// The default height quantum: 1/16 m, finer than the vertical accuracy of any common DEM and a
/// power of two, so quanta convert to metres exactly.
pub const DEFAULT_HEIGHT_QUANTUM: f32 = 0.0625;

impl Default for BuildOptions {
    fn default() -> Self {
        BuildOptions {
            tile_size: 129,
            spacing: None,
            vertical_scale: 1.0,
            origin: None,
            texture_factor: 1,
            texture_image: None,
            codec: Codec::Lz4,
            height_quantum: None,
            base_levels: 1,
        }
    }
}

/// What a build produced.
#[derive(Clone, Debug, Serialize)]
pub struct BuildReport {
    /// The archive header as written.
    pub header: Header,
    /// Archive length in bytes.
    pub archive_bytes: u64,
    /// Sum of the uncompressed tile payloads.
    pub raw_payload_bytes: u64,
    /// Sum of the stored tile payloads.
    pub stored_payload_bytes: u64,
    /// What the build assumed or chose that the user should know: the reader's reading of the
    /// file (geographic grid, degree cells, 8-bit samples), a coarser height quantum.
    pub notes: Vec<String>,
    /// Wall-clock seconds.
    pub seconds: f64,
}

/// Builds `out` from `reader`; `progress` is called with (tiles done, tiles total).
pub fn build<R: DemReader>(
    reader: NodataFill<R>,
    out: &Path,
    options: &BuildOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<BuildReport> {
    let started = Instant::now();
    let info = reader.info().clone();
    let mut notes = info.notes.clone();
    let columns = match (options.spacing, info.east_west_scale) {
        (None, scale) if scale != 1.0 => Some(EastWest::new(info.width, scale)),
        _ => None,
    };
    if let Some(c) = columns {
        notes.push(format!(
            "{} columns resampled to {} east-west",
            c.source_width(),
            c.width()
        ));
    }
    if let (Some(s), true) = (options.spacing, info.east_west_scale != 1.0) {
        notes.push(format!(
            "--spacing {s} overrides the file's georeferencing: square cells of {s} m"
        ));
    }
    match (options.spacing, info.spacing_hint, &info.spacing_problem) {
        (None, _, Some(problem)) => return Err(Error::invalid(&info.name, problem.clone())),
        (None, None, None) => notes.push(
            "the file does not say how far apart its samples are: 1 m taken; pass --spacing \
             METRES"
                .to_string(),
        ),
        _ => {}
    }
    let width = columns.map_or(info.width, |c| c.width());
    let grid = Tiling::new(width, info.height, options.tile_size)?;
    let header = header(&info, &grid, options)?;
    let image = match &options.texture_image {
        Some(path) => Some(ImageTexture::open(path, grid.width, info.height)?),
        None => None,
    };
    for stale in partial::remove_stale(out) {
        notes.push(format!(
            "removed {}, left by a build that was killed",
            stale.display()
        ));
    }
    let mut writer = ArchiveWriter::create(out, header.clone())?;
    let mut bands = BandReader::new(reader, grid, options.vertical_scale as f32, columns);
    let mut totals = Totals::default();
    let mut done = 0;
    let (mut north, mut next) = (None, bands.next_band()?.cloned());
    while let Some(current) = next.take() {
        next = bands.next_band()?.cloned();
        let window = BandWindow {
            north: north.as_ref(),
            current: &current,
            south: next.as_ref(),
        };
        let encoded = encode_band(&window, &header, image.as_ref(), options, &info.name)?;
        for (tx, tile) in encoded.into_iter().enumerate() {
            writer.write_tile(current.tile_row * grid.tiles_x + tx, &tile.chunks)?;
            totals.add(&tile);
        }
        done += grid.tiles_x;
        progress(done, grid.tile_count());
        north = Some(current);
    }
    let nodata = bands.fill_stats();
    let archive_bytes = writer.finish(totals.min, totals.max, nodata)?;
    Ok(BuildReport {
        header: Header {
            min_height: totals.min,
            max_height: totals.max,
            nodata_filled: nodata.filled,
            nodata_flattened: nodata.flattened,
            ..header
        },
        archive_bytes,
        raw_payload_bytes: totals.raw_bytes,
        stored_payload_bytes: totals.stored_bytes,
        notes,
        seconds: started.elapsed().as_secs_f64(),
    })
}

/// Opens the DEM `path` as `open` says and builds `out` from it ([`build`]). When the height
/// quantum is left to the build and a tile's relief does not fit 65535 quanta of the default,
/// it builds again with the smallest power-of-two quantum that fits, and says so in the
/// report's notes.
pub fn build_file(
    path: &Path,
    open: &OpenOptions,
    out: &Path,
    options: &BuildOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<BuildReport> {
    let mut options = options.clone();
    let automatic = options.height_quantum.is_none();
    loop {
        match build(dem::open(path, open)?, out, &options, progress) {
            Err(Error::HeightRange {
                relief, quantum, ..
            }) if automatic => {
                let mut fitting = quantum * 2.0;
                while f64::from(relief) / f64::from(fitting) > f64::from(u16::MAX) - 1.0 {
                    fitting *= 2.0;
                }
                options.height_quantum = Some(fitting);
            }
            Ok(mut report) => {
                let q = report.header.height_quantum;
                if automatic && q != DEFAULT_HEIGHT_QUANTUM {
                    report.notes.push(format!(
                        "height quantum {q} m: the relief of some tiles does not fit 65535 \
                         quanta of the default {DEFAULT_HEIGHT_QUANTUM} m (heights are within \
                         {} m of the source; --height-quantum sets it)",
                        q / 2.0
                    ));
                }
                return Ok(report);
            }
            Err(e) => return Err(e),
        }
    }
}

/// The archive header for `info` cut as `grid`, once `options` are checked (the height range
/// is filled in when every tile is known).
fn header(info: &DemInfo, grid: &Tiling, options: &BuildOptions) -> Result<Header> {
    let f = options.texture_factor;
    if !f.is_power_of_two() || f > 8 {
        return Err(Error::setting(
            "texture factor",
            f,
            "a power of two up to 8",
        ));
    }
    let spacing = options.spacing.or(info.spacing_hint).unwrap_or(1.0);
    if !(spacing.is_finite() && spacing > 0.0) {
        return Err(Error::setting(
            "spacing",
            spacing,
            "a positive number of metres",
        ));
    }
    if !options.vertical_scale.is_finite() || options.vertical_scale == 0.0 {
        return Err(Error::setting(
            "vertical scale",
            options.vertical_scale,
            "a finite non-zero number of metres per unit",
        ));
    }
    if spacing > MAX_SPACING {
        return Err(Error::setting(
            "spacing",
            spacing,
            format!("at most {MAX_SPACING} metres"),
        ));
    }
    if let Some((x, y)) = options.origin {
        if !(x.is_finite() && y.is_finite()) {
            return Err(Error::setting(
                "origin",
                format!("{x} {y}"),
                "two finite numbers of metres",
            ));
        }
    }
    // A tile far larger than the DEM is all padding: refuse it rather than encode it (any size
    // up to the default is allowed, so the default always works).
    let side = info.width.max(info.height).max(2);
    let needed = ((side - 1).next_power_of_two() + 1).max(BuildOptions::default().tile_size);
    if grid.tile_size > needed {
        return Err(Error::setting(
            "tile size",
            grid.tile_size,
            format!(
                "at most {needed} for a {} x {} DEM (one tile of {needed} holds it all)",
                info.width, info.height
            ),
        ));
    }
    let too_wide = |what: &str| {
        Error::invalid(
            &info.name,
            format!("{what} does not fit the archive's 32-bit fields"),
        )
    };
    let (origin_x, origin_y) = options.origin.or(info.origin_hint).unwrap_or((0.0, 0.0));
    let header = Header {
        tiles_x: u32::try_from(grid.tiles_x).map_err(|_| too_wide("the tile count"))?,
        tiles_y: u32::try_from(grid.tiles_y).map_err(|_| too_wide("the tile count"))?,
        tile_size: grid.tile_size as u32,
        texture_size: ((grid.tile_size - 1) * f) as u32,
        codec: options.codec,
        source_width: u32::try_from(grid.width).map_err(|_| too_wide("the width"))?,
        source_height: u32::try_from(info.height).map_err(|_| too_wide("the height"))?,
        spacing,
        vertical_scale: options.vertical_scale,
        origin_x,
        origin_y,
        min_height: 0.0,
        max_height: 0.0,
        height_quantum: options.height_quantum.unwrap_or(DEFAULT_HEIGHT_QUANTUM),
        base_levels: options.base_levels.min(progressive_levels(grid.tile_size)) as u32,
        nodata_filled: 0,
        nodata_flattened: 0,
    };
    // Everything else a reader checks (tile counts, index size, extent), before anything is
    // read or written.
    header.validate(&info.name)?;
    Ok(header)
}

/// One tile ready to write: its compressed progressive chunks, coarse first.
struct EncodedTile {
    chunks: Vec<Vec<u8>>,
    /// Uncompressed bytes of the chunks.
    raw_len: usize,
    min: f32,
    max: f32,
}

/// Encodes the tiles of the window's current band, in parallel, in column order: heights
/// quantised, the apron read from the neighbouring samples, the texture cut from `image` or
/// shaded from the heights, each level compressed on its own. `name` (the DEM's) labels errors.
fn encode_band(
    window: &BandWindow<'_>,
    header: &Header,
    image: Option<&ImageTexture>,
    options: &BuildOptions,
    name: &str,
) -> Result<Vec<EncodedTile>> {
    let (s, texture_size) = (header.tile_size as usize, header.texture_size as usize);
    let (f, ty, band) = (
        options.texture_factor,
        window.current.tile_row,
        window.current,
    );
    (0..header.tiles_x as usize)
        .into_par_iter()
        .map(|tx| {
            let heights = band.tile_heights(tx);
            let texture = match image {
                Some(img) => img.cut(tx, ty, s, f),
                None => shaded(s, header.spacing as f32, f, |x, y| {
                    match (usize::try_from(x), usize::try_from(y)) {
                        (Ok(i), Ok(j)) if i < s && j < s => Some(heights[j * s + i]),
                        _ => window.around(tx, x, y),
                    }
                }),
            };
            let quantum = header.height_quantum;
            let tile = Tile::new(&heights, s, quantum, &texture, texture_size)
                .map_err(|problem| {
                    let (lo, hi) = heights
                        .iter()
                        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &h| {
                            (lo.min(h), hi.max(h))
                        });
                    if f64::from(hi - lo) / f64::from(quantum) > f64::from(u16::MAX) - 1.0 {
                        Error::HeightRange {
                            name: name.to_string(),
                            tile_x: tx,
                            tile_y: ty,
                            relief: hi - lo,
                            quantum,
                        }
                    } else {
                        Error::invalid(name, format!("tile ({tx}, {ty}): {problem}"))
                    }
                })?
                .with_apron(|x, y| window.around(tx, x, y));
            let (mut chunks, mut raw_len) = (Vec::with_capacity(tile.levels), 0);
            for g in 0..tile.levels {
                let raw = tile.encode_level(g);
                raw_len += raw.len();
                chunks.push(compress(&raw, options.codec));
            }
            Ok(EncodedTile {
                chunks,
                raw_len,
                min: tile.min,
                max: tile.max,
            })
        })
        .collect()
}

/// What the tiles written so far add up to.
struct Totals {
    min: f32,
    max: f32,
    raw_bytes: u64,
    stored_bytes: u64,
}

impl Default for Totals {
    fn default() -> Self {
        Totals {
            min: f32::INFINITY,
            max: f32::NEG_INFINITY,
            raw_bytes: 0,
            stored_bytes: 0,
        }
    }
}

impl Totals {
    fn add(&mut self, tile: &EncodedTile) {
        self.raw_bytes += tile.raw_len as u64;
        self.stored_bytes += tile.chunks.iter().map(|c| c.len() as u64).sum::<u64>();
        self.min = self.min.min(tile.min);
        self.max = self.max.max(tile.max);
    }
}
