//! Build an archive from a synthetic DEM and read it back through the file source.

use std::path::Path;

use stripmask::db::archive::{ArchiveReader, Codec, HEADER_LEN};
use stripmask::db::builder::{BuildOptions, build};
use stripmask::db::dem::{MemoryReader, NodataFill};
use stripmask::db::level_error::level_errors;
use stripmask::db::source::file::FileSource;

/// A 70 x 45 DEM (not a multiple of the tile step, so the east and south edges are padded).
fn synthetic(width: usize, height: usize) -> Vec<f32> {
    (0..width * height)
        .map(|k| {
            let (i, j) = ((k % width) as f32, (k / width) as f32);
            1000.0 + 300.0 * (i * 0.13).sin() * (j * 0.07).cos() + 2.0 * i - j
        })
        .collect()
}

fn build_synthetic(dir: &Path, codec: Codec) -> (std::path::PathBuf, Vec<f32>) {
    let (w, h) = (70, 45);
    let samples = synthetic(w, h);
    let reader = MemoryReader::new("synthetic", w, h, samples.clone()).unwrap();
    let out = dir.join("synthetic.smdb");
    let options = BuildOptions {
        tile_size: 17,
        spacing: Some(25.0),
        vertical_scale: 0.5,
        codec,
        ..BuildOptions::default()
    };
    build(NodataFill::new(reader, None), &out, &options, &|_, _| {}).unwrap();
    (out, samples)
}

#[test]
fn every_sample_reads_back_within_half_a_quantum_with_shared_borders_and_padding() {
    for codec in [Codec::Lz4, Codec::None, Codec::Deflate] {
        let dir = tempfile::tempdir().unwrap();
        let (path, samples) = build_synthetic(dir.path(), codec);
        let reader = ArchiveReader::open(FileSource::open(&path).unwrap()).unwrap();
        let h = reader.header().clone();
        assert_eq!((h.tiles_x, h.tiles_y, h.tile_size), (5, 3, 17));
        assert_eq!((h.source_width, h.source_height), (70, 45));
        assert_eq!(h.texture_size, 16);
        assert_eq!(h.codec, codec);
        let expect = |i: usize, j: usize| samples[j.min(44) * 70 + i.min(69)] * 0.5;
        for ty in 0..3 {
            for tx in 0..5 {
                let tile = reader.tile(tx, ty).unwrap();
                assert_eq!(tile.level_errors.len(), 16);
                assert_eq!(tile.texture_mips.len(), 5);
                let mut truth = Vec::new();
                for j in 0..17 {
                    for i in 0..17 {
                        let t = expect(tx * 16 + i, ty * 16 + j);
                        truth.push(t);
                        let got = tile.height(i, j);
                        assert!(
                            (got - t).abs() <= tile.quantum * 0.5 + 1e-3,
                            "tile ({tx}, {ty}) sample ({i}, {j}): {got} vs {t}"
                        );
                    }
                }
                assert_eq!(tile.level_errors, level_errors(&truth, 17));
                assert!(tile.min <= tile.max);
                assert!(tile.min >= h.min_height && tile.max <= h.max_height);
            }
        }
        // Neighbours agree exactly on the integer heights of their shared samples.
        let (a, b) = (reader.tile(0, 0).unwrap(), reader.tile(1, 0).unwrap());
        let c = reader.tile(0, 1).unwrap();
        for k in 0..17 {
            assert_eq!(a.quanta(16, k), b.quanta(0, k));
            assert_eq!(a.quanta(k, 16), c.quanta(k, 0));
        }
    }
}

#[test]
fn the_index_finds_tiles_in_o1_and_the_main_file_is_header_plus_index() {
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = build_synthetic(dir.path(), Codec::Lz4);
    let reader = ArchiveReader::open(FileSource::open(&path).unwrap()).unwrap();
    let h = reader.header();
    // 17-sample tiles have 5 progressive levels: an entry is 8 + 5 * 8 bytes.
    assert_eq!(h.payload_start(), (HEADER_LEN + 15 * 48 + 4) as u64);
    let mut next = h.payload_start();
    for e in reader.index() {
        assert_eq!(e.offset, next, "payloads are contiguous in tile order");
        next += e.stored_len();
    }
    // Then the base: every tile's first level again, in tile order.
    assert_eq!(h.base_levels, 1);
    let base: u64 = reader.index().iter().map(|e| e.prefix_len(1)).sum();
    assert_eq!(next + base, std::fs::metadata(&path).unwrap().len());
    let (tiles, stored) = reader.base().unwrap();
    assert_eq!(stored, base);
    assert_eq!(tiles.len(), 15);
    for (i, tile) in tiles.iter().enumerate() {
        let (x, y) = (i % h.tiles_x as usize, i / h.tiles_x as usize);
        assert_eq!(
            *tile,
            reader.tile_levels(x, y, 1).unwrap().0,
            "base tile {i}"
        );
    }
    assert!(!dir.path().join("synthetic.smdb.partial").exists());
}

#[test]
fn a_colour_image_is_cut_into_tile_textures_aligned_with_the_samples() {
    let dir = tempfile::tempdir().unwrap();
    // West half red, east half blue, one pixel per sample of a 65 x 33 DEM.
    let (w, h) = (65u32, 33u32);
    let img = image::RgbImage::from_fn(w, h, |x, _| {
        if x < 32 {
            image::Rgb([200, 0, 0])
        } else {
            image::Rgb([0, 0, 200])
        }
    });
    let texture = dir.path().join("ortho.png");
    img.save(&texture).unwrap();
    let reader = MemoryReader::new("flat", 65, 33, vec![10.0; 65 * 33]).unwrap();
    let out = dir.path().join("t.smdb");
    let options = BuildOptions {
        tile_size: 17,
        texture_image: Some(texture),
        texture_factor: 2,
        ..BuildOptions::default()
    };
    build(NodataFill::new(reader, None), &out, &options, &|_, _| {}).unwrap();
    let archive = ArchiveReader::open(FileSource::open(&out).unwrap()).unwrap();
    assert_eq!(archive.header().texture_size, 32);
    let red = stripmask_raster::rgb_to_rgb565([200, 0, 0]);
    let blue = stripmask_raster::rgb_to_rgb565([0, 0, 200]);
    let west = archive.tile(0, 0).unwrap();
    let east = archive.tile(3, 1).unwrap();
    assert_eq!(west.texture_mips.len(), 6);
    assert!(west.texture_mips[0].iter().all(|&t| t == red));
    assert!(east.texture_mips[0].iter().all(|&t| t == blue));
    assert_eq!(*west.texture_mips[5].first().unwrap(), red);
}
