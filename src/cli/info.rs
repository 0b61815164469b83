//! `stripmask info`: what an archive holds, and with `--check` whether every tile reads.

use std::time::Instant;

use clap::Args;
use serde::Serialize;
use stripmask::db::archive::{ArchiveReader, HEADER_LEN, Header};
use stripmask::db::source;
use stripmask::error::Result;

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

#[derive(Serialize)]
pub(super) struct InfoReport {
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

#[derive(Serialize)]
pub(super) struct CheckReport {
    tiles: usize,
    bytes: u64,
    seconds: f64,
    tiles_per_second: f64,
    mebibytes_per_second: f64,
}

pub(super) fn run(a: InfoArgs) -> Result<()> {
    let source = source::open(&a.file_or_url)?;
    let file_bytes = source.size()?;
    let reader = ArchiveReader::open(source)?;
    let h = reader.header().clone();
    let lengths: Vec<u64> = reader.index().iter().map(|e| e.stored_len()).collect();
    let stored_level_bytes_mean = (0..h.levels())
        .map(|g| {
            let sum: u64 = reader.index().iter().map(|e| e.range(g..g + 1).1).sum();
            sum as f64 / lengths.len().max(1) as f64
        })
        .collect();
    let check = if a.check {
        let started = Instant::now();
        let mut bytes = 0;
        for ty in 0..h.tiles_y as usize {
            for tx in 0..h.tiles_x as usize {
                reader.tile(tx, ty)?;
                bytes += lengths[ty * h.tiles_x as usize + tx];
            }
        }
        let seconds = started.elapsed().as_secs_f64().max(1e-9);
        Some(CheckReport {
            tiles: h.tile_count(),
            bytes,
            seconds,
            tiles_per_second: h.tile_count() as f64 / seconds,
            mebibytes_per_second: bytes as f64 / seconds / (1024.0 * 1024.0),
        })
    } else {
        None
    };
    let report = InfoReport {
        name: a.file_or_url.clone(),
        version: stripmask::db::archive::VERSION,
        tile_count: h.tile_count(),
        file_bytes,
        main_bytes: (HEADER_LEN + h.index_len()) as u64,
        raw_tile_bytes: h.payload_size(),
        stored_tile_bytes_min: lengths.iter().copied().min().unwrap_or(0),
        stored_tile_bytes_mean: lengths.iter().map(|&l| l as f64).sum::<f64>()
            / lengths.len().max(1) as f64,
        stored_tile_bytes_max: lengths.iter().copied().max().unwrap_or(0),
        stored_tile_bytes: lengths,
        raw_level_bytes: (0..h.levels()).map(|g| h.level_payload_size(g)).collect(),
        stored_level_bytes_mean,
        header: h,
        check,
    };
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&report).expect("serialisable")
        );
        return Ok(());
    }
    let h = &report.header;
    let mut out = String::new();
    let mut line = |s: String| {
        out.push_str(&s);
        out.push('\n');
    };
    line(format!(
        "archive     {} (format version {})",
        report.name, report.version
    ));
    line(format!(
        "grid        {} x {} tiles of {} x {} samples, from a {} x {} DEM",
        h.tiles_x, h.tiles_y, h.tile_size, h.tile_size, h.source_width, h.source_height
    ));
    line(format!(
        "spacing     {} m, vertical scale {} m per unit, origin ({}, {})",
        h.spacing, h.vertical_scale, h.origin_x, h.origin_y
    ));
    line(format!(
        "heights     {} .. {} m in quanta of {} m",
        h.min_height, h.max_height, h.height_quantum
    ));
    line(format!(
        "texture     {0} x {0} RGB565 per tile with mipmaps; payload codec {1:?}",
        h.texture_size, h.codec
    ));
    line(format!(
        "bytes       {} in all; header + index {}; per tile {} raw, stored {} / {:.0} / {} (min / mean / max)",
        report.file_bytes,
        report.main_bytes,
        report.raw_tile_bytes,
        report.stored_tile_bytes_min,
        report.stored_tile_bytes_mean,
        report.stored_tile_bytes_max
    ));
    let levels: Vec<String> = report
        .raw_level_bytes
        .iter()
        .zip(&report.stored_level_bytes_mean)
        .map(|(raw, stored)| format!("{raw} -> {stored:.0}"))
        .collect();
    line(format!(
        "levels      {} progressive, bytes per tile raw -> stored (mean), coarse first: {}",
        levels.len(),
        levels.join(", ")
    ));
    if let Some(c) = &report.check {
        line(format!(
            "check       {} tiles verified and decoded in {:.3} s: {:.1} tiles/s, {:.2} MiB/s",
            c.tiles, c.seconds, c.tiles_per_second, c.mebibytes_per_second
        ));
    }
    print!("{out}");
    Ok(())
}
