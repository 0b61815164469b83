//! `stripmask build`: stream a DEM band by band, encode each tile of every level of the
//! pyramid, write the archive.
//!
//! Memory held at once, per level of the pyramid (each half as wide as the one below): three
//! bands of `s` rows of the padded width (f32) — the band being encoded and its neighbours
//! north and south, which the tiles' aprons ([`crate::db::tile::Apron`]) are read from — and
//! the band being put together from the level below ([`crate::db::pyramid::Assembly`]), with
//! what the level below's tiles left for their parents; for level 0 also which samples were
//! nodata, one input row, the reader's own strip or tile row, the nodata fill's window of rows
//! ([`crate::db::dem::NodataFill`]); the encoded tiles of one band (they are encoded in
//! parallel, then written in order); the writer's index pages and the coarsest levels
//! ([`ArchiveWriter`]); and the texture image when one is given.

use std::path::{Path, PathBuf};
use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;

use std::collections::HashMap;

use crate::db::archive::{
    ArchiveWriter, Codec, Header, MAX_SPACING, compress, partial, pyramid_levels,
};
use crate::db::dem::{self, DemInfo, DemReader, EastWest, NodataFill, OpenOptions};
use crate::db::georef::Georef;
use crate::db::grid::TileId;
use crate::db::pyramid::{Assembly, ChildInfo, combined_errors, level_tilings, parent_texture};
use crate::db::texture_gen::{ImageTexture, shaded};
use crate::db::tile::Tile;
use crate::db::tiling::{Band, BandReader, BandWindow, Tiling};
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
    /// samples; the model's relief must fit 65535 quanta (4096 m at the default 1/16 m), as the
    /// pyramid's root holds all of it. `None`: [`DEFAULT_HEIGHT_QUANTUM`], which [`build_file`]
    /// coarsens to a power of two that fits when the relief needs it.
    pub height_quantum: Option<f32>,
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
    /// Tiles stored, of every level (absent ones are not).
    pub stored_tiles: u64,
    /// What the build assumed or chose that the user should know: the reader's reading of the
    /// file (geographic grid, degree cells, 8-bit samples), a coarser height quantum.
    pub notes: Vec<String>,
    /// The CRS the DEM's georeferencing names, as read, and its unit.
    pub crs: Option<String>,
    /// The process's peak resident memory so far in bytes (Linux's `VmHWM`): for
    /// `stripmask build`, the build's.
    pub peak_memory_bytes: Option<u64>,
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
    let header = Header {
        georef: georef(&info, columns),
        ..header(&info, &grid, options)?
    };
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
    let writer = ArchiveWriter::create(out, header.clone())?;
    let mut bands = BandReader::new(reader, grid, options.vertical_scale as f32, columns);
    let mut pyramid = Pipeline::new(
        level_tilings(grid),
        writer,
        Encoding {
            header: &header,
            image: image.as_ref(),
            options,
            name: &info.name,
        },
        progress,
    );
    let automatic = options.height_quantum.is_none();
    while let Some(band) = bands.next_band()? {
        let band = band.clone();
        if automatic {
            check_relief(bands.height_range(), &header, &info.name)?;
        }
        pyramid.push(0, band)?;
    }
    pyramid.flush(0)?;
    let nodata = bands.fill_stats();
    let Pipeline { writer, totals, .. } = pyramid;
    let (min, max) = (totals.min, totals.max);
    let header = writer.finish(min, max, nodata)?;
    Ok(BuildReport {
        archive_bytes: header.archive_len,
        header,
        raw_payload_bytes: totals.raw_bytes,
        stored_payload_bytes: totals.stored_bytes,
        stored_tiles: totals.tiles,
        notes,
        crs: info
            .placement
            .as_ref()
            .map(|p| format!("{} ({})", p.crs, p.unit_name())),
        peak_memory_bytes: peak_memory(),
        seconds: started.elapsed().as_secs_f64(),
    })
}

/// The process's peak resident memory in bytes, where the system says (Linux).
fn peak_memory() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Fails with [`Error::HeightRange`] once the heights read so far span more than 65535 quanta
/// of `header`'s quantum: the pyramid's root, which covers the whole model, could not hold
/// them. Raised as soon as it is known, so that [`build_file`] starts again early with a
/// coarser quantum.
fn check_relief((lo, hi): (f32, f32), header: &Header, name: &str) -> Result<()> {
    let quantum = header.height_quantum;
    if f64::from(hi - lo) / f64::from(quantum) > f64::from(u16::MAX) - 1.0 {
        return Err(Error::HeightRange {
            name: name.to_string(),
            what: "the model (which the pyramid's root holds whole)".into(),
            relief: hi - lo,
            quantum,
        });
    }
    Ok(())
}

/// Opens the DEM `path` as `open` says and builds `out` from it ([`build_opening`]).
pub fn build_file(
    path: &Path,
    open: &OpenOptions,
    out: &Path,
    options: &BuildOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<BuildReport> {
    build_opening(|| dem::open(path, open), out, options, progress)
}

/// Opens the DEM `inputs` name (one file, or a mosaic of many: [`dem::open_inputs`]) and
/// builds `out` from it ([`build_opening`]).
pub fn build_inputs(
    inputs: &[PathBuf],
    open: &OpenOptions,
    out: &Path,
    options: &BuildOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<BuildReport> {
    build_opening(|| dem::open_inputs(inputs, open), out, options, progress)
}

/// Builds `out` from the DEM `open` opens ([`build`]). When the height quantum is left to the
/// build and the model's relief does not fit 65535 quanta of the default, it opens the DEM
/// again and builds with the smallest power-of-two quantum that fits, and says so in the
/// report's notes; the build stops as soon as the relief read so far does not fit.
pub fn build_opening<R: DemReader>(
    mut open: impl FnMut() -> Result<NodataFill<R>>,
    out: &Path,
    options: &BuildOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<BuildReport> {
    let mut options = options.clone();
    let automatic = options.height_quantum.is_none();
    loop {
        match build(open()?, out, &options, progress) {
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
                        "height quantum {q} m: the model's relief does not fit 65535 quanta of \
                         the default {DEFAULT_HEIGHT_QUANTUM} m (heights are within {} m of the \
                         source; --height-quantum sets it)",
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
    if let Some((x, y)) = options.origin
        && !(x.is_finite() && y.is_finite())
    {
        return Err(Error::setting(
            "origin",
            format!("{x} {y}"),
            "two finite numbers of metres",
        ));
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
    let tiles_x = u32::try_from(grid.tiles_x).map_err(|_| too_wide("the tile count"))?;
    let tiles_y = u32::try_from(grid.tiles_y).map_err(|_| too_wide("the tile count"))?;
    let header = Header {
        tiles_x,
        tiles_y,
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
        nodata_filled: 0,
        nodata_flattened: 0,
        absent_tiles: 0,
        top_level: pyramid_levels(tiles_x, tiles_y) as u32 - 1,
        top_offset: 0,
        top_len: 0,
        archive_len: 0,
        georef: None,
    };
    // Everything else a reader checks (tile counts, index size, extent), before anything is
    // read or written.
    header.validate(&info.name)?;
    Ok(header)
}

/// Where the archive's samples lie in the DEM's CRS, when it has one: its placement, with
/// columns `columns` resampled as much closer together as they are.
fn georef(info: &DemInfo, columns: Option<EastWest>) -> Option<Georef> {
    let p = info.placement.as_ref().filter(|p| p.named)?;
    let step = columns.map_or(1.0, |_| 1.0 / info.east_west_scale);
    Some(Georef {
        crs: p.crs.clone(),
        units: p.units,
        first: p.first,
        cell: (p.cell.0 * step, p.cell.1),
    })
}

/// What encoding a tile reads besides its band: the archive's header, the texture image,
/// the options, and the DEM's name for errors.
#[derive(Clone, Copy)]
struct Encoding<'a> {
    header: &'a Header,
    image: Option<&'a ImageTexture>,
    options: &'a BuildOptions,
    name: &'a str,
}

/// One tile ready to write: its compressed progressive chunks, coarse first (none when it is
/// absent), and what it leaves for its parent.
struct EncodedTile {
    chunks: Option<Vec<Vec<u8>>>,
    /// Uncompressed bytes of the chunks.
    raw_len: usize,
    min: f32,
    max: f32,
    child: ChildInfo,
}

/// One level of the pyramid as the build goes: the bands around the one being encoded, the
/// band of the level above being put together from this one's, and what this level's tiles
/// left for their parents.
struct Level {
    tiling: Tiling,
    north: Option<Band>,
    current: Option<Band>,
    up: Option<Assembly>,
    children: HashMap<(usize, usize), ChildInfo>,
}

/// The pyramid's levels, the writer, and what the tiles written add up to.
struct Pipeline<'a> {
    levels: Vec<Level>,
    writer: ArchiveWriter,
    encoding: Encoding<'a>,
    totals: Totals,
    done: usize,
    total: usize,
    progress: &'a (dyn Fn(usize, usize) + Sync),
}

impl<'a> Pipeline<'a> {
    fn new(
        tilings: Vec<Tiling>,
        writer: ArchiveWriter,
        encoding: Encoding<'a>,
        progress: &'a (dyn Fn(usize, usize) + Sync),
    ) -> Self {
        let total = tilings.iter().map(Tiling::tile_count).sum();
        let levels = tilings
            .iter()
            .enumerate()
            .map(|(k, &tiling)| Level {
                tiling,
                north: None,
                current: None,
                up: tilings.get(k + 1).map(|&t| Assembly::new(t)),
                children: HashMap::new(),
            })
            .collect();
        Pipeline {
            levels,
            writer,
            encoding,
            totals: Totals::default(),
            done: 0,
            total,
            progress,
        }
    }

    /// Takes in level `k`'s next band: encodes the band before it (whose southern neighbour
    /// it is), then adds it to the level above, which may complete a band there.
    fn push(&mut self, k: usize, band: Band) -> Result<()> {
        if let Some(current) = self.levels[k].current.take() {
            let north = self.levels[k].north.take();
            self.encode(k, north.as_ref(), &current, Some(&band))?;
            self.levels[k].north = Some(current);
        }
        let above = self.levels[k].up.as_mut().and_then(|up| up.add(&band));
        self.levels[k].current = Some(band);
        match above {
            Some(above) => self.push(k + 1, above),
            None => Ok(()),
        }
    }

    /// Encodes level `k`'s last band, hands the level above its last (half) band, and flushes
    /// it in turn.
    fn flush(&mut self, k: usize) -> Result<()> {
        if let Some(current) = self.levels[k].current.take() {
            let north = self.levels[k].north.take();
            self.encode(k, north.as_ref(), &current, None)?;
        }
        if k + 1 < self.levels.len() {
            if let Some(last) = self.levels[k].up.as_mut().and_then(Assembly::finish) {
                self.push(k + 1, last)?;
            }
            self.flush(k + 1)?;
        }
        Ok(())
    }

    /// Encodes and writes the tiles of level `k`'s band `current`, keeping what they leave for
    /// their parents.
    fn encode(
        &mut self,
        k: usize,
        north: Option<&Band>,
        current: &Band,
        south: Option<&Band>,
    ) -> Result<()> {
        let window = BandWindow {
            north,
            current,
            south,
        };
        let ty = current.tile_row;
        let children = (k > 0).then(|| {
            let below = &self.levels[k - 1];
            let (cols, rows) = (below.tiling.tiles_x, below.tiling.tiles_y);
            (0..self.levels[k].tiling.tiles_x)
                .map(|tx| {
                    [(0, 0), (1, 0), (0, 1), (1, 1)].map(|(dx, dy)| {
                        let (x, y) = (2 * tx + dx, 2 * ty + dy);
                        (x < cols && y < rows).then(|| {
                            below
                                .children
                                .get(&(x, y))
                                .expect("a level's tiles are encoded before their parents")
                        })
                    })
                })
                .collect::<Vec<_>>()
        });
        let encoded = encode_band(&window, k, children.as_deref(), self.encoding)?;
        if k > 0 {
            let below = &mut self.levels[k - 1];
            below.children.retain(|&(_, y), _| y / 2 != ty);
        }
        let keep = k + 1 < self.levels.len();
        for (tx, tile) in encoded.into_iter().enumerate() {
            let id = TileId::at(k as u8, tx as u32, ty as u32);
            match tile.chunks {
                Some(chunks) => {
                    self.totals
                        .add(k, tile.raw_len, &chunks, tile.min, tile.max);
                    self.writer.write_tile(id, chunks)?;
                }
                None => self.writer.write_absent(id)?,
            }
            if keep {
                self.levels[k].children.insert((tx, ty), tile.child);
            }
        }
        self.done += self.levels[k].tiling.tiles_x;
        (self.progress)(self.done, self.total);
        Ok(())
    }
}

/// Encodes the tiles of the window's current band of level `level`, in parallel, in column
/// order: heights quantised, the apron read from the neighbouring samples, the texture cut
/// from the image or shaded from the heights (level 0) or put together from the children's
/// (`children`, per column: north-west, north-east, south-west, south-east), the errors
/// against full resolution, each level compressed on its own. A level-0 tile whose every
/// sample was nodata, and a tile above whose children are all absent, is absent.
fn encode_band(
    window: &BandWindow<'_>,
    level: usize,
    children: Option<&[[Option<&ChildInfo>; 4]]>,
    encoding: Encoding<'_>,
) -> Result<Vec<EncodedTile>> {
    let Encoding {
        header,
        image,
        options,
        name,
    } = encoding;
    let (s, texture_size) = (header.tile_size as usize, header.texture_size as usize);
    let (f, ty, band) = (
        options.texture_factor,
        window.current.tile_row,
        window.current,
    );
    let spacing = (header.spacing * f64::from(1u32 << level)) as f32;
    (0..band.grid().tiles_x)
        .into_par_iter()
        .map(|tx| {
            let heights = band.tile_heights(tx);
            let below = children.map(|c| c[tx]);
            let absent = match below {
                None => band.tile_is_nodata(tx),
                Some(c) => c.iter().flatten().all(|c| c.absent),
            };
            if absent {
                return Ok(EncodedTile {
                    chunks: None,
                    raw_len: 0,
                    min: f32::INFINITY,
                    max: f32::NEG_INFINITY,
                    child: ChildInfo::absent(&heights, s, texture_size),
                });
            }
            let texture = match (below, image) {
                (Some(c), _) => parent_texture(c, texture_size),
                (None, Some(img)) => img.cut(tx, ty, s, f),
                (None, None) => shaded(s, spacing, f, |x, y| {
                    match (usize::try_from(x), usize::try_from(y)) {
                        (Ok(i), Ok(j)) if i < s && j < s => Some(heights[j * s + i]),
                        _ => window.around(tx, x, y),
                    }
                }),
            };
            let quantum = header.height_quantum;
            let mut tile = Tile::new(&heights, s, quantum, &texture, texture_size)
                .map_err(|problem| {
                    let what = TileId::at(level as u8, tx as u32, ty as u32);
                    let (lo, hi) = heights
                        .iter()
                        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &h| {
                            (lo.min(h), hi.max(h))
                        });
                    if f64::from(hi - lo) / f64::from(quantum) > f64::from(u16::MAX) - 1.0 {
                        Error::HeightRange {
                            name: name.to_string(),
                            what: what.to_string(),
                            relief: hi - lo,
                            quantum,
                        }
                    } else {
                        Error::invalid(name, format!("{what}: {problem}"))
                    }
                })?
                .with_apron(|x, y| window.around(tx, x, y));
            if let Some(c) = below {
                let present: Vec<&ChildInfo> = c.iter().flatten().copied().collect();
                tile.level_errors = combined_errors(&heights, s, &present);
            }
            let (mut chunks, mut raw_len) = (Vec::with_capacity(tile.levels), 0);
            for g in 0..tile.levels {
                let raw = tile.encode_level(g);
                raw_len += raw.len();
                chunks.push(compress(&raw, options.codec));
            }
            Ok(EncodedTile {
                chunks: Some(chunks),
                raw_len,
                min: tile.min,
                max: tile.max,
                child: ChildInfo::present(tile.level_errors, &texture, texture_size),
            })
        })
        .collect()
}

/// What the tiles written so far add up to.
struct Totals {
    /// The lowest and highest height of level 0's present tiles.
    min: f32,
    max: f32,
    raw_bytes: u64,
    stored_bytes: u64,
    tiles: u64,
}

impl Default for Totals {
    fn default() -> Self {
        Totals {
            min: f32::INFINITY,
            max: f32::NEG_INFINITY,
            raw_bytes: 0,
            stored_bytes: 0,
            tiles: 0,
        }
    }
}

impl Totals {
    fn add(&mut self, level: usize, raw_len: usize, chunks: &[Vec<u8>], min: f32, max: f32) {
        self.raw_bytes += raw_len as u64;
        self.stored_bytes += chunks.iter().map(|c| c.len() as u64).sum::<u64>();
        self.tiles += 1;
        if level == 0 {
            self.min = self.min.min(min);
            self.max = self.max.max(max);
        }
    }
}
