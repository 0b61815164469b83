//! The synthetic archive the engine tests fly over.

use std::path::{Path, PathBuf};

use stripmask::db::builder::{BuildOptions, build};
use stripmask::db::dem::{MemoryReader, NodataFill};

/// A 257 x 257 DEM of hills, 30 m apart, cut into tiles of `tile_size` samples (33: 8 x 8 tiles),
/// written into `dir`.
pub fn archive(dir: &Path, tile_size: usize) -> PathBuf {
    let n = 257;
    let samples = (0..n * n)
        .map(|k| {
            let (i, j) = ((k % n) as f32, (k / n) as f32);
            400.0 + 250.0 * (i * 0.05).sin() * (j * 0.04).cos() + 80.0 * (i * 0.21 + j * 0.17).sin()
        })
        .collect();
    let reader = MemoryReader::new("hills", n, n, samples).unwrap();
    let out = dir.join(format!("hills{tile_size}.smdb"));
    let options = BuildOptions {
        tile_size,
        spacing: Some(30.0),
        texture_factor: 1,
        ..BuildOptions::default()
    };
    build(NodataFill::new(reader, None), &out, &options, &|_, _| {}).unwrap();
    out
}
