//! `stripmask info`: what an archive holds, and with `--check` whether every tile reads.

use clap::Args;
use serde::Serialize;
use stripmask::db::archive::{ArchiveReader, CheckReport, HEADER_LEN, Header, VERSION};
use stripmask::db::source;
use stripmask::error::Result;

/// `info`'s arguments: the archive and the output form.
#[derive(Args, Debug)]
pub(super) struct InfoArgs {
    /// An archive file or http:// URL.
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
    tile_count: usize,
    file_bytes: u64,
    main_bytes: u64,
    raw_tile_bytes: usize,
    stored_tile_bytes_min: u64,
    stored_tile_bytes_mean: f64,
    stored_tile_bytes_max: u64,
    stored_tile_bytes: Vec<u64>,
    raw_level_bytes: Vec<usize>,
    stored_level_bytes_mean: Vec<f64>,
    check: Option<CheckReport>,
}

/// Prints the archive's report, as text or JSON.
pub(super) fn run(a: InfoArgs) -> Result<()> {
    let report = InfoReport::read(&a.file_or_url, a.check)?;
    if a.json {
        say!(
            "{}",
            serde_json::to_string_pretty(&report).expect("serialisable")
        );
    } else {
        say_raw!("{}", report.text());
    }
    Ok(())
}

impl InfoReport {
    /// What the archive `name` (a file or URL) holds; with `check`, every tile verified too.
    fn read(name: &str, check: bool) -> Result<InfoReport> {
        let source = source::open(name)?;
        let file_bytes = source.size()?;
        let reader = ArchiveReader::open(source)?;
        let h = reader.header().clone();
        let lengths: Vec<u64> = reader.index().iter().map(|e| e.stored_len()).collect();
        let tiles = lengths.len().max(1) as f64;
        let stored_level_bytes_mean = (0..h.levels())
            .map(|g| {
                let sum: u64 = reader.index().iter().map(|e| e.range(g..g + 1).1).sum();
                sum as f64 / tiles
            })
            .collect();
        Ok(InfoReport {
            name: name.to_string(),
            version: VERSION,
            tile_count: h.tile_count(),
            file_bytes,
            main_bytes: (HEADER_LEN + h.index_len()) as u64,
            raw_tile_bytes: h.payload_size(),
            stored_tile_bytes_min: lengths.iter().copied().min().unwrap_or(0),
            stored_tile_bytes_mean: lengths.iter().map(|&l| l as f64).sum::<f64>() / tiles,
            stored_tile_bytes_max: lengths.iter().copied().max().unwrap_or(0),
            stored_tile_bytes: lengths,
            raw_level_bytes: (0..h.levels()).map(|g| h.level_payload_size(g)).collect(),
            stored_level_bytes_mean,
            check: if check { Some(reader.check()?) } else { None },
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
                "bytes       {} in all; header + index {}; per tile {} raw, stored {} / {:.0} / {} \
                 (min / mean / max)",
                self.file_bytes,
                self.main_bytes,
                self.raw_tile_bytes,
                self.stored_tile_bytes_min,
                self.stored_tile_bytes_mean,
                self.stored_tile_bytes_max
            ),
            format!(
                "levels      {} progressive, bytes per tile raw -> stored (mean), coarse first: {}",
                levels.len(),
                levels.join(", ")
            ),
        ];
        if let Some(c) = &self.check {
            lines.push(format!(
                "check       {} tiles verified and decoded in {:.3} s: {:.1} tiles/s, {:.2} MiB/s",
                c.tiles, c.seconds, c.tiles_per_second, c.mebibytes_per_second
            ));
        }
        lines.iter().map(|l| format!("{l}\n")).collect()
    }
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
