//! A DEM larger than any one decode: a tiled GeoTIFF of 10,812² Float32 samples (467 MB
//! decoded, above the `tiff` crate's 256 MiB limit on one decode, the size of a 3DEP 1/3"
//! tile) builds in memory bounded by a band of tiles.

use crate::support::cli::stripmask;
use crate::support::tiff_writer::{Chunking, Layout, raw, tiff_of};

/// The side of the model, and of its TIFF tiles.
const SIDE: u32 = 10_812;
const TILE: u32 = 512;

#[cfg(target_os = "linux")]
#[test]
fn a_tiled_geotiff_larger_than_one_decode_builds_in_a_band_of_memory() {
    // Data in one row of TIFF tiles across the whole width, the rest stored as empty tiles
    // (nodata): every row is still read, and the rows of data are a band 512 deep.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("big.tif");
    let band = 10 * TILE..11 * TILE;
    let height = |i: u32, j: u32| -> f32 {
        if band.contains(&j) {
            100.0 + (i % 1000) as f32 * 0.5 + (j - band.start) as f32 * 0.25
        } else {
            f32::NAN
        }
    };
    let layout = Layout::new(Chunking::Tiles(TILE, TILE));
    let bytes = tiff_of((SIDE, SIDE), height, &layout, |chunk, _| {
        if chunk.iter().all(|v| v.is_nan()) {
            Vec::new()
        } else {
            raw(chunk, false)
        }
    });
    std::fs::write(&path, bytes).unwrap();
    let out = dir.path().join("big.smdb");
    let built = stripmask()
        .args(["build", "--json", "--tile-size", "129", "-o"])
        .arg(&out)
        .arg(&path)
        .output()
        .unwrap();
    assert!(
        built.status.success(),
        "{}",
        String::from_utf8_lossy(&built.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&built.stdout).unwrap();
    // The build's own reading of its peak (VmHWM): a forked child's rusage would count the
    // test process's memory too.
    let peak = report["peak_memory_bytes"].as_u64().unwrap();
    let decoded = u64::from(SIDE) * u64::from(SIDE) * 4;
    assert!(decoded > 256 << 20);
    // A band of 512 rows of the TIFF and the builder's bands of 129: tens of MB, not the
    // 467 MB of the whole grid.
    assert!(
        peak < decoded / 4,
        "peak memory {} MB for a grid of {} MB",
        peak >> 20,
        decoded >> 20
    );
    let info = stripmask()
        .args(["info", "--json"])
        .arg(&out)
        .output()
        .unwrap();
    let info: serde_json::Value = serde_json::from_slice(&info.stdout).unwrap();
    assert_eq!(info["header"]["source_width"], SIDE);
    assert!(info["header"]["absent_tiles"].as_u64().unwrap() > 5000);
}
