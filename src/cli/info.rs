//! `stripmask info`: what an archive holds, and with `--check` whether every tile reads.

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Args;
use serde::Serialize;
use stripmask::db::archive::{ArchiveReader, CheckReport, Header, IndexEntry, VERSION};
use stripmask::db::dem::{DemFormat, OpenOptions, Units, expand, open_inputs};
use stripmask::db::source;
use stripmask::error::Result;

/// `info`'s arguments: the archive (or DEM) and the output form.
#[derive(Args, Debug)]
pub(super) struct InfoArgs {
    /// An archive file or http:// URL; or a DEM (a file, a GDAL .vrt, a folder or glob
    /// pattern of tiles) to see how `build` reads it.
    file_or_url: String,
    /// Print JSON.
    #[arg(long)]
    json: bool,
    /// Also fetch, verify and decode every tile, and report the rate.
    #[arg(long)]
    check: bool,
}

/// What `info` prints, as text or JSON.
#[derive(Serialize)]
struct InfoReport {
    name: String,
    version: u32,
    header: Header,
    tile_count: u64,
    /// Tiles across and down every level of the pyramid, level 0 first.
    pyramid: Vec<(u32, u32)>,
    file_bytes: u64,
    /// Bytes an open reads: the header and the directory.
    opening_bytes: u64,
    top_tiles: usize,
    raw_tile_bytes: usize,
    raw_level_bytes: Vec<usize>,
    /// Stored bytes per progressive level, mean over the tiles measured: the top's, or every
    /// tile's with `--check`.
    stored_level_bytes_mean: Vec<f64>,
    /// Which tiles the means are over.
    measured: &'static str,
    /// CRS coordinates of the model's corner samples (NW, NE, SW, SE), when georeferenced.
    corners: Option<[(f64, f64); 4]>,
    check: Option<CheckReport>,
}

/// Prints the archive's (or the DEM's) report, as text or JSON.
pub(super) fn run(a: InfoArgs) -> Result<()> {
    if names_a_dem(&a.file_or_url) {
        let report = DemReport::read(&a.file_or_url, a.check)?;
        print(&report, a.json, || report.text());
    } else {
        let report = InfoReport::read(&a.file_or_url, a.check)?;
        print(&report, a.json, || report.text());
    }
    Ok(())
}

/// Prints `report` as JSON, or as its `text`.
fn print<T: Serialize>(report: &T, json: bool, text: impl Fn() -> String) {
    if json {
        say!(
            "{}",
            serde_json::to_string_pretty(report).expect("serialisable")
        );
    } else {
        say_raw!("{}", text());
    }
}

impl InfoReport {
    /// What the archive `name` (a file or URL) holds, read from its header and directory; with
    /// `check`, every tile verified too.
    fn read(name: &str, check: bool) -> Result<InfoReport> {
        let source = source::open(name)?;
        let file_bytes = source.size()?;
        let reader = ArchiveReader::open(source)?;
        let h = reader.header().clone();
        let pyramid = reader.pyramid();
        let top: Vec<&IndexEntry> = reader
            .directory()
            .top
            .iter()
            .map(|(_, e)| e)
            .filter(|e| !e.is_absent())
            .collect();
        let tiles = top.len().max(1) as f64;
        let mut stored_level_bytes_mean: Vec<f64> = (0..h.levels())
            .map(|g| top.iter().map(|e| e.range(g..g + 1).1).sum::<u64>() as f64 / tiles)
            .collect();
        let check = if check { Some(reader.check()?) } else { None };
        let mut measured = "the top's tiles";
        if let Some(c) = &check {
            stored_level_bytes_mean = c.stored_level_bytes_mean.clone();
            measured = "every tile";
        }
        Ok(InfoReport {
            name: name.to_string(),
            version: VERSION,
            tile_count: h.tile_count(),
            pyramid: (0..pyramid.levels())
                .map(|k| {
                    let g = pyramid.grid(k as u8);
                    (g.tiles_x(), g.tiles_y())
                })
                .collect(),
            file_bytes,
            opening_bytes: reader.opening_bytes(),
            top_tiles: reader.directory().top.len(),
            raw_tile_bytes: h.payload_size(),
            raw_level_bytes: (0..h.levels()).map(|g| h.level_payload_size(g)).collect(),
            stored_level_bytes_mean,
            measured,
            check,
            corners: h.corners(),
            header: h,
        })
    }

    /// The report as lines of text, one topic per line.
    fn text(&self) -> String {
        let h = &self.header;
        let levels: Vec<String> = self
            .raw_level_bytes
            .iter()
            .zip(&self.stored_level_bytes_mean)
            .map(|(raw, stored)| format!("{raw} -> {stored:.0}"))
            .collect();
        let mut lines = vec![
            format!(
                "archive     {} (format version {})",
                self.name, self.version
            ),
            format!(
                "grid        {} x {} tiles of {} x {} samples, from a {} x {} DEM",
                h.tiles_x, h.tiles_y, h.tile_size, h.tile_size, h.source_width, h.source_height
            ),
            format!(
                "extent      {:.0} x {:.0} m of model ({} x {} samples); the tiles cover {:.0} x {:.0} m, padded with {} column(s) east and {} row(s) south that are never drawn",
                f64::from(h.source_width.saturating_sub(1)) * h.spacing,
                f64::from(h.source_height.saturating_sub(1)) * h.spacing,
                h.source_width,
                h.source_height,
                f64::from(h.tiles_x * (h.tile_size - 1)) * h.spacing,
                f64::from(h.tiles_y * (h.tile_size - 1)) * h.spacing,
                (h.tiles_x * (h.tile_size - 1) + 1).saturating_sub(h.source_width),
                (h.tiles_y * (h.tile_size - 1) + 1).saturating_sub(h.source_height),
            ),
            format!(
                "spacing     {} m, vertical scale {} m per unit, origin ({}, {})",
                h.spacing, h.vertical_scale, h.origin_x, h.origin_y
            ),
            crs_line(h),
        ];
        lines.extend(self.corners.map(|c| {
            let at = |(x, y): (f64, f64)| format!("({x}, {y})");
            format!(
                "corners     NW {}, NE {}, SW {}, SE {} (sample centres, in the CRS's units)",
                at(c[0]),
                at(c[1]),
                at(c[2]),
                at(c[3])
            )
        }));
        lines.extend([
            format!(
                "heights     {} .. {} m (valid samples) in quanta of {} m",
                h.min_height, h.max_height, h.height_quantum
            ),
            nodata_line(h),
            format!(
                "texture     {0} x {0} RGB565 per tile with mipmaps; payload codec {1:?}",
                h.texture_size, h.codec
            ),
            format!(
                "pyramid     {} levels: {}",
                self.pyramid.len(),
                self.pyramid
                    .iter()
                    .map(|(x, y)| format!("{x} x {y}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
            absent_line(h),
            format!(
                "bytes       {} in all; an open reads {}; the top holds {} tiles of levels {} .. \
                 {} in {} bytes; a whole tile is {} raw",
                self.file_bytes,
                self.opening_bytes,
                self.top_tiles,
                h.top_level,
                self.pyramid.len() - 1,
                h.top_len,
                self.raw_tile_bytes,
            ),
            format!(
                "levels      {} progressive, bytes per tile raw -> stored (mean over {}), coarse \
                 first: {}",
                levels.len(),
                self.measured,
                levels.join(", ")
            ),
        ]);
        if let Some(c) = &self.check {
            lines.push(format!(
                "check       {} tiles of every level verified and decoded ({} absent) in {:.3} s: \
                 {:.1} tiles/s, {:.2} MiB/s",
                c.tiles, c.absent, c.seconds, c.tiles_per_second, c.mebibytes_per_second
            ));
        }
        lines.iter().map(|l| format!("{l}\n")).collect()
    }
}

/// The archive's CRS, or that it has none.
fn crs_line(h: &Header) -> String {
    match &h.georef {
        Some(g) => {
            let unit = match g.units {
                Units::Degrees => "degrees".to_string(),
                Units::Linear(m) => format!("linear units of {m} m"),
                Units::WebMercator(m) => format!("Web Mercator units of {m} m"),
            };
            format!(
                "crs         {} ({unit}); {} x {} CRS units between columns and rows",
                g.crs, g.cell.0, g.cell.1
            )
        }
        None => {
            "crs         none stored: positions are given in the archive's own coordinates".into()
        }
    }
}

/// The level-0 tiles stored as absent: `build` and `info` print it.
pub(super) fn absent_line(h: &Header) -> String {
    if h.absent_tiles == 0 {
        return "absent      none: every tile holds data".into();
    }
    format!(
        "absent      {} of {} level-0 tiles are all nodata: stored as nothing, drawn as nothing",
        h.absent_tiles,
        h.tile_count()
    )
}

/// What the build made up where the source had no data: `build` and `info` print it.
pub(super) fn nodata_line(h: &Header) -> String {
    if h.nodata_filled + h.nodata_flattened == 0 {
        return "nodata      none: every sample is the source's".into();
    }
    format!(
        "nodata      {} samples filled from their nearest valid neighbours, {} in large nodata \
         areas drawn flat at the lowest valid height around them",
        h.nodata_filled, h.nodata_flattened
    )
}

/// Whether `name` is a DEM rather than an archive: a folder, a glob pattern, or a file whose
/// extension names a DEM format.
fn names_a_dem(name: &str) -> bool {
    let path = Path::new(name);
    !name.contains("://")
        && (path.is_dir()
            || DemFormat::from_path(path).is_some()
            || (!path.exists() && name.contains(['*', '?', '['])))
}

/// What `info` says of a DEM: how `build` would read and place it.
#[derive(Serialize)]
struct DemReport {
    name: String,
    files: usize,
    width: usize,
    height: usize,
    /// The CRS as read, and its unit.
    crs: Option<String>,
    /// Cell size east-west and north-south, in the CRS's units.
    cell: Option<(f64, f64)>,
    /// CRS coordinates of the north-west sample's centre.
    first_sample: Option<(f64, f64)>,
    /// Metres between rows, as `build` takes them.
    spacing_m: Option<f64>,
    /// East-west spacing over north-south: `build` resamples columns when it is not 1.
    east_west_scale: f64,
    /// World position in metres of the north-west sample, as `build` stores it.
    origin_m: Option<(f64, f64)>,
    /// Why `build` would need `--spacing`.
    spacing_problem: Option<String>,
    notes: Vec<String>,
    check: Option<DemCheck>,
}

/// What reading every row of a DEM took, with `--check`.
#[derive(Serialize)]
struct DemCheck {
    seconds: f64,
    samples_per_second: f64,
    nodata_filled: u64,
    nodata_flattened: u64,
}

impl DemReport {
    /// How the DEM `name` reads; with `check`, every row read too.
    fn read(name: &str, check: bool) -> Result<DemReport> {
        let inputs = [PathBuf::from(name)];
        let files = expand(&inputs)?.len();
        let mut reader = open_inputs(&inputs, &OpenOptions::default())?;
        let info = reader.info().clone();
        let check = if check {
            let started = Instant::now();
            let mut row = vec![0.0; info.width];
            for _ in 0..info.height {
                reader.read_row(&mut row)?;
            }
            let seconds = started.elapsed().as_secs_f64();
            let stats = reader.stats();
            Some(DemCheck {
                seconds,
                samples_per_second: (info.width * info.height) as f64 / seconds.max(1e-9),
                nodata_filled: stats.filled,
                nodata_flattened: stats.flattened,
            })
        } else {
            None
        };
        let p = info.placement.as_ref();
        Ok(DemReport {
            name: info.name.clone(),
            files,
            width: info.width,
            height: info.height,
            crs: p.map(|p| format!("{} ({})", p.crs, p.unit_name())),
            cell: p.map(|p| p.cell),
            first_sample: p.map(|p| p.first),
            spacing_m: info.spacing_hint,
            east_west_scale: info.east_west_scale,
            origin_m: info.origin_hint,
            spacing_problem: info.spacing_problem,
            notes: info.notes,
            check,
        })
    }

    /// The report as lines of text.
    fn text(&self) -> String {
        let mut lines = vec![
            format!(
                "dem         {} ({} file{})",
                self.name,
                self.files,
                if self.files == 1 { "" } else { "s" }
            ),
            format!("grid        {} x {} samples", self.width, self.height),
            format!(
                "crs         {}",
                self.crs.as_deref().unwrap_or("none given")
            ),
        ];
        if let (Some(c), Some(f)) = (self.cell, self.first_sample) {
            lines.push(format!(
                "placement   cells of {} x {}, north-west sample at ({}, {}), in the CRS's units",
                c.0, c.1, f.0, f.1
            ));
        }
        lines.push(match (self.spacing_m, &self.spacing_problem) {
            (_, Some(problem)) => format!("spacing     unknown: {problem}"),
            (Some(s), None) => format!(
                "spacing     {s} m north-south, {} m east-west{}",
                s * self.east_west_scale,
                self.origin_m
                    .map_or(String::new(), |(x, y)| format!(", origin ({x}, {y}) m"))
            ),
            (None, None) => "spacing     not given: `build` takes 1 m unless --spacing".into(),
        });
        lines.extend(self.notes.iter().map(|n| format!("note        {n}")));
        if let Some(c) = &self.check {
            lines.push(format!(
                "check       every row read in {:.3} s ({:.1} M samples/s); {} nodata samples \
                 filled, {} drawn flat",
                c.seconds,
                c.samples_per_second / 1e6,
                c.nodata_filled,
                c.nodata_flattened
            ));
        }
        lines.iter().map(|l| format!("{l}\n")).collect()
    }
}
