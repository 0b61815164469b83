//! The synthetic archives the engine tests fly over.

use std::path::{Path, PathBuf};

use stripmask::db::builder::{BuildOptions, build};
use stripmask::db::dem::{MemoryReader, NodataFill};
use stripmask::engine::paging::PagerMode;
use stripmask::{EngineSettings, FrameTiming};

/// An engine's settings for the hills: `memory_limit_bytes`, every wanted tile fetched a few at
/// a time on the frame's thread, one rasterizer thread, frame times told (so budgets repeat).
pub fn stepped(memory_limit_bytes: usize) -> EngineSettings {
    EngineSettings {
        memory_limit_bytes,
        pager_mode: PagerMode::Stepped {
            fetches_per_update: 64,
        },
        threads: 1,
        frame_timing: FrameTiming::Told,
        ..EngineSettings::default()
    }
}

/// Builds `dir/NAME.smdb` with `options` from a `w x h` DEM whose sample in column `i`, row `j`
/// is `height(i, j)`.
pub fn synthetic(
    dir: &Path,
    name: &str,
    (w, h): (usize, usize),
    options: &BuildOptions,
    height: impl Fn(usize, usize) -> f32,
) -> PathBuf {
    let samples = (0..w * h).map(|k| height(k % w, k / w)).collect();
    let reader = MemoryReader::new(name, w, h, samples).unwrap();
    let out = dir.join(format!("{name}.smdb"));
    build(NodataFill::new(reader, None), &out, options, &|_, _| {}).unwrap();
    out
}

/// A 257 x 257 DEM of hills, 30 m apart, cut into tiles of `tile_size` samples (33: 8 x 8 tiles),
/// written into `dir`.
pub fn archive(dir: &Path, tile_size: usize) -> PathBuf {
    let options = BuildOptions {
        tile_size,
        spacing: Some(30.0),
        texture_factor: 1,
        ..BuildOptions::default()
    };
    synthetic(
        dir,
        &format!("hills{tile_size}"),
        (257, 257),
        &options,
        |i, j| {
            let (i, j) = (i as f32, j as f32);
            400.0 + 250.0 * (i * 0.05).sin() * (j * 0.04).cos() + 80.0 * (i * 0.21 + j * 0.17).sin()
        },
    )
}
