//! `stripmask build`: a DEM in, an archive out.

use std::path::PathBuf;

use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use stripmask::db::archive::Codec;
use stripmask::db::builder::{BuildOptions, build};
use stripmask::db::dem::{self, DemFormat, OpenOptions, RawLayout, SampleType};
use stripmask::error::Result;

#[derive(Args, Debug)]
pub(super) struct BuildArgs {
    /// The DEM file.
    pub(super) input: PathBuf,
    /// The archive to write.
    #[arg(short, long)]
    pub(super) output: PathBuf,
    /// Input format (default: from the extension).
    #[arg(long, value_enum)]
    pub(super) format: Option<DemFormat>,
    /// Raw/BIL: samples per row.
    #[arg(long, requires_all = ["height", "sample_type"])]
    pub(super) width: Option<usize>,
    /// Raw/BIL: rows.
    #[arg(long, requires_all = ["width", "sample_type"])]
    pub(super) height: Option<usize>,
    /// Raw/BIL: sample type.
    #[arg(long, value_enum, requires_all = ["width", "height"])]
    pub(super) sample_type: Option<SampleType>,
    /// Raw/BIL: samples are big-endian (default little-endian).
    #[arg(long)]
    pub(super) big_endian: bool,
    /// Raw/BIL: bytes to skip before the first sample.
    #[arg(long, default_value_t = 0)]
    pub(super) header_bytes: u64,
    /// A raw value that means "no data" (in addition to the file's own).
    #[arg(long, allow_negative_numbers = true)]
    pub(super) nodata: Option<f32>,
    /// Samples per tile side, 2^n + 1.
    #[arg(long, default_value_t = 129)]
    pub(super) tile_size: usize,
    /// Metres between samples (default: the file's georeferencing, else 1).
    #[arg(long)]
    pub(super) spacing: Option<f64>,
    /// Metres per raw height unit.
    #[arg(long, default_value_t = 1.0)]
    pub(super) vertical_scale: f64,
    /// World x, y of the north-west sample (default: the file's georeferencing, else 0, 0).
    #[arg(long, num_args = 2, value_names = ["X", "Y"], allow_negative_numbers = true)]
    pub(super) origin: Option<Vec<f64>>,
    /// A colour image covering the DEM, cut into tile textures (default: ramp + hill shading).
    #[arg(long)]
    pub(super) texture: Option<PathBuf>,
    /// Texels per grid cell in tile textures (1, 2, 4 or 8).
    #[arg(long, default_value_t = 1)]
    pub(super) texture_factor: usize,
    /// How tile payloads are stored.
    #[arg(long, value_enum, default_value_t = Codec::Lz4)]
    pub(super) codec: Codec,
    /// Metres per height quantum, shared by all tiles; a tile's relief must fit 65535 quanta.
    #[arg(long, default_value_t = stripmask::db::builder::DEFAULT_HEIGHT_QUANTUM)]
    pub(super) height_quantum: f32,
    /// No progress bar and no summary.
    #[arg(short, long)]
    pub(super) quiet: bool,
    /// Print the summary as JSON.
    #[arg(long)]
    pub(super) json: bool,
}

pub(super) fn run(a: BuildArgs) -> Result<()> {
    let raw = match (a.width, a.height, a.sample_type) {
        (Some(width), Some(height), Some(sample_type)) => Some(RawLayout {
            width,
            height,
            sample_type,
            big_endian: a.big_endian,
            header_bytes: a.header_bytes,
        }),
        _ => None,
    };
    let reader = dem::open(
        &a.input,
        &OpenOptions {
            format: a.format,
            raw,
            nodata: a.nodata,
        },
    )?;
    let options = BuildOptions {
        tile_size: a.tile_size,
        spacing: a.spacing,
        vertical_scale: a.vertical_scale,
        origin: a.origin.map(|o| (o[0], o[1])),
        texture_factor: a.texture_factor,
        texture_image: a.texture,
        codec: a.codec,
        height_quantum: a.height_quantum,
        ..BuildOptions::default()
    };
    let bar = if a.quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(0).with_style(
            ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {pos}/{len} tiles {eta}")
                .expect("valid template")
                .progress_chars("=> "),
        )
    };
    let report = build(reader, &a.output, &options, &|done, total| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    })?;
    bar.finish_and_clear();
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&report).expect("serialisable")
        );
    } else if !a.quiet {
        let h = &report.header;
        println!(
            "{}: {} x {} tiles of {} samples, {} bytes ({:.1} KiB per tile stored, {:.1} KiB raw) in {:.2} s",
            a.output.display(),
            h.tiles_x,
            h.tiles_y,
            h.tile_size,
            report.archive_bytes,
            report.stored_payload_bytes as f64 / h.tile_count() as f64 / 1024.0,
            report.raw_payload_bytes as f64 / h.tile_count() as f64 / 1024.0,
            report.seconds
        );
    }
    Ok(())
}
