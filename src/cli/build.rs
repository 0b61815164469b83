//! `stripmask build`: a DEM in, an archive out.

use std::fs::Metadata;
use std::path::{Path, PathBuf};

use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use stripmask::Named;
use stripmask::db::archive::Codec;
use stripmask::db::builder::{BuildOptions, BuildReport, build_inputs};
use stripmask::db::dem::{DemFormat, HeightEncoding, OpenOptions, RawLayout, SampleType, expand};
use stripmask::error::{Error, Result};

use super::args::named;

/// `build`'s arguments: the DEM, how to read it, and what to make of it.
#[derive(Args, Debug)]
pub(super) struct BuildArgs {
    /// The DEM: a file, a GDAL .vrt, or many files (names, folders, glob patterns) read as one
    /// mosaic placed by their georeferencing.
    #[arg(required = true, num_args = 1..)]
    inputs: Vec<PathBuf>,
    /// The archive to write.
    #[arg(short, long)]
    output: PathBuf,
    /// Input format (default: from the extension).
    #[arg(long, value_parser = named::<DemFormat>())]
    format: Option<DemFormat>,
    /// How a PNG's pixels hold heights: gray levels, or the web maps' Mapbox Terrain-RGB or
    /// Terrarium tiles (heights in metres).
    #[arg(long, value_parser = named::<HeightEncoding>(), default_value = HeightEncoding::Gray.name())]
    encoding: HeightEncoding,
    /// Raw/BIL: samples per row.
    #[arg(long, requires_all = ["height", "sample_type"])]
    width: Option<usize>,
    /// Raw/BIL: rows.
    #[arg(long, requires_all = ["width", "sample_type"])]
    height: Option<usize>,
    /// Raw/BIL: sample type.
    #[arg(long, value_parser = named::<SampleType>(), requires_all = ["width", "height"])]
    sample_type: Option<SampleType>,
    /// Raw/BIL: samples are big-endian (default little-endian).
    #[arg(long)]
    big_endian: bool,
    /// Raw/BIL: bytes to skip before the first sample.
    #[arg(long, default_value_t = 0)]
    header_bytes: u64,
    /// A raw value that means "no data" (in addition to the file's own).
    #[arg(long, allow_negative_numbers = true)]
    nodata: Option<f32>,
    /// Samples per tile side, 2^n + 1.
    #[arg(long, default_value_t = BuildOptions::default().tile_size)]
    tile_size: usize,
    /// Metres between samples on both axes (default: the file's georeferencing, in metres on
    /// both axes for grids in degrees, else 1).
    #[arg(long, allow_negative_numbers = true)]
    spacing: Option<f64>,
    /// Metres per raw height unit.
    #[arg(long, default_value_t = BuildOptions::default().vertical_scale, allow_negative_numbers = true)]
    vertical_scale: f64,
    /// World x, y of the north-west sample (default: the file's georeferencing, else 0, 0).
    #[arg(long, num_args = 2, value_names = ["X", "Y"], allow_negative_numbers = true)]
    origin: Option<Vec<f64>>,
    /// A colour image covering the DEM, cut into tile textures (default: ramp + hill shading).
    #[arg(long)]
    texture: Option<PathBuf>,
    /// Texels per grid cell in tile textures (1, 2, 4 or 8).
    #[arg(long, default_value_t = BuildOptions::default().texture_factor)]
    texture_factor: usize,
    /// How tile payloads are stored (deflate: smaller, slower to decode).
    #[arg(long, value_parser = named::<Codec>(), default_value = BuildOptions::default().codec.name())]
    codec: Codec,
    /// Metres per height quantum, shared by all tiles; the model's relief must fit 65535 quanta
    /// (default: 1/16 m, or the smallest power of two that fits, with a note).
    #[arg(long)]
    height_quantum: Option<f32>,
    /// No progress bar and no summary.
    #[arg(short, long)]
    quiet: bool,
    /// Print the summary as JSON.
    #[arg(long)]
    json: bool,
}

impl BuildArgs {
    /// How the DEM is read.
    fn open_options(&self) -> OpenOptions {
        let raw = match (self.width, self.height, self.sample_type) {
            (Some(width), Some(height), Some(sample_type)) => Some(RawLayout {
                width,
                height,
                sample_type,
                big_endian: self.big_endian,
                header_bytes: self.header_bytes,
            }),
            _ => None,
        };
        OpenOptions {
            format: self.format,
            raw,
            nodata: self.nodata,
            encoding: self.encoding,
        }
    }

    /// What the build makes of it.
    fn build_options(&self) -> BuildOptions {
        BuildOptions {
            tile_size: self.tile_size,
            spacing: self.spacing,
            vertical_scale: self.vertical_scale,
            origin: self.origin.as_ref().map(|o| (o[0], o[1])),
            texture_factor: self.texture_factor,
            texture_image: self.texture.clone(),
            codec: self.codec,
            height_quantum: self.height_quantum,
        }
    }
}

/// Builds the archive with a progress bar and prints its summary (text or JSON).
pub(super) fn run(a: BuildArgs) -> Result<()> {
    let inputs = expand(&a.inputs)?;
    let read = inputs
        .iter()
        .map(|i| ("input", i.as_path()))
        .chain(a.texture.iter().map(|t| ("texture", t.as_path())));
    refuse_output_over(&a.output, read)?;
    let options = a.build_options();
    let bar = if a.quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(0).with_style(
            ProgressStyle::with_template(
                "{elapsed_precise} [{bar:40}] {human_pos}/{human_len} samples, {per_sec}, {eta} left",
            )
            .expect("valid template")
            .progress_chars("=> "),
        )
    };
    // Every tile of every level encodes (s - 1)^2 samples' worth of work.
    let samples = ((options.tile_size.max(2) - 1) as u64).pow(2);
    let report = build_inputs(
        &inputs,
        &a.open_options(),
        &a.output,
        &options,
        &|done, total| {
            bar.set_length(total as u64 * samples);
            bar.set_position(done as u64 * samples);
        },
    )?;
    bar.finish_and_clear();
    if a.json {
        say!(
            "{}",
            serde_json::to_string_pretty(&report).expect("serialisable")
        );
    } else if !a.quiet {
        say_raw!("{}", summary(&a.output, &report));
    }
    Ok(())
}

/// The text summary of a build: the archive, then the numbers a user should check.
fn summary(output: &std::path::Path, report: &BuildReport) -> String {
    let h = &report.header;
    let tiles = h.pyramid().tile_count();
    let stored = report.stored_tiles.max(1);
    let mut lines = vec![
        format!(
            "{}: {} x {} tiles of {} samples and {} levels above them ({} tiles in all), {} \
             bytes ({:.1} KiB per tile stored, {:.1} KiB raw) in {:.2} s",
            output.display(),
            h.tiles_x,
            h.tiles_y,
            h.tile_size,
            h.pyramid_levels() - 1,
            tiles,
            report.archive_bytes,
            report.stored_payload_bytes as f64 / stored as f64 / 1024.0,
            report.raw_payload_bytes as f64 / stored as f64 / 1024.0,
            report.seconds
        ),
        format!(
            "spacing     {} m between samples, origin ({}, {})",
            h.spacing, h.origin_x, h.origin_y
        ),
        format!(
            "crs         {}",
            report.crs.as_deref().unwrap_or("none given")
        ),
        format!(
            "memory      {} at peak (resident, the whole process)",
            report
                .peak_memory_bytes
                .map_or("unknown".into(), |b| format!("{:.1} MB", b as f64 / 1e6))
        ),
        format!(
            "heights     {} .. {} m (valid samples), {} m per raw unit, in quanta of {} m",
            h.min_height, h.max_height, h.vertical_scale, h.height_quantum
        ),
    ];
    lines.extend(report.notes.iter().map(|n| format!("note        {n}")));
    if h.nodata_filled + h.nodata_flattened > 0 {
        lines.push(super::info::nodata_line(h));
    }
    if h.absent_tiles > 0 {
        lines.push(super::info::absent_line(h));
    }
    lines.iter().map(|l| format!("{l}\n")).collect()
}

/// Refuses an `output` that is one of the files the build reads (the DEM, the texture image):
/// the same file through any path, symbolic link or hard link, by canonical path and, on unix,
/// by device and inode. Nothing is read before: the build would replace its own input.
fn refuse_output_over<'a>(
    output: &Path,
    inputs: impl Iterator<Item = (&'static str, &'a Path)>,
) -> Result<()> {
    // An output that does not exist yet is no input.
    let Ok(written) = std::fs::metadata(output) else {
        return Ok(());
    };
    let canonical = std::fs::canonicalize(output).ok();
    for (role, input) in inputs {
        let Ok(read) = std::fs::metadata(input) else {
            continue;
        };
        let same_path = canonical.is_some() && canonical == std::fs::canonicalize(input).ok();
        if same_path || same_inode(&written, &read) {
            return Err(Error::OutputIsInput {
                output: output.display().to_string(),
                role,
                input: input.display().to_string(),
            });
        }
    }
    Ok(())
}

#[cfg(unix)]
fn same_inode(a: &Metadata, b: &Metadata) -> bool {
    use std::os::unix::fs::MetadataExt;
    (a.dev(), a.ino()) == (b.dev(), b.ino())
}

#[cfg(not(unix))]
fn same_inode(_: &Metadata, _: &Metadata) -> bool {
    false
}
