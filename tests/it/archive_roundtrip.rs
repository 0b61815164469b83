//! Build an archive from a synthetic DEM and read it back through the file source.

use std::path::Path;

use stripmask::db::archive::{ArchiveReader, Codec, HEADER_LEN};
use stripmask::db::builder::{BuildOptions, build};
use stripmask::db::dem::{MemoryReader, NodataFill};
use stripmask::db::grid::TileId;
use stripmask::db::level_error::level_errors;
use stripmask::db::source::CancelToken;
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
                let tile = reader.tile(TileId::new(tx, ty)).unwrap().unwrap();
                assert_eq!(tile.level_errors.len(), 16);
                assert_eq!(tile.texture_mips.len(), 5);
                let mut truth = Vec::new();
                for j in 0..17 {
                    for i in 0..17 {
                        let t = expect(tx as usize * 16 + i, ty as usize * 16 + j);
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
        let tile = |x, y| reader.tile(TileId::new(x, y)).unwrap().unwrap();
        let (a, b, c) = (tile(0, 0), tile(1, 0), tile(0, 1));
        for k in 0..17 {
            assert_eq!(a.quanta(16, k), b.quanta(0, k));
            assert_eq!(a.quanta(k, 16), c.quanta(k, 0));
        }
    }
}

#[test]
fn every_level_of_the_pyramid_holds_every_other_sample_of_the_level_below_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = build_synthetic(dir.path(), Codec::Lz4);
    let reader = ArchiveReader::open(FileSource::open(&path).unwrap()).unwrap();
    let pyramid = reader.pyramid().clone();
    let sizes: Vec<(u32, u32)> = (0..pyramid.levels())
        .map(|k| {
            (
                pyramid.grid(k as u8).tiles_x(),
                pyramid.grid(k as u8).tiles_y(),
            )
        })
        .collect();
    assert_eq!(sizes, [(5, 3), (3, 2), (2, 1), (1, 1)]);
    // The integer height of level-0 sample (x, y) (clamped to the padded grid), from level 0.
    let level0 = |x: u32, y: u32| {
        let (x, y) = (x.min(5 * 16), y.min(3 * 16));
        let (tx, ty) = ((x / 16).min(4), (y / 16).min(2));
        let t = reader.tile(TileId::new(tx, ty)).unwrap().unwrap();
        t.quanta((x - tx * 16) as usize, (y - ty * 16) as usize)
    };
    for k in 1..pyramid.levels() as u8 {
        let grid = pyramid.grid(k);
        for ty in 0..grid.tiles_y() {
            for tx in 0..grid.tiles_x() {
                let tile = reader.tile(TileId::at(k, tx, ty)).unwrap().unwrap();
                let step = 1u32 << k;
                for j in 0..17u32 {
                    for i in 0..17u32 {
                        let (x, y) = ((tx * 16 + i) * step, (ty * 16 + j) * step);
                        assert_eq!(
                            tile.quanta(i as usize, j as usize),
                            level0(x, y),
                            "level {k} tile ({tx}, {ty}) sample ({i}, {j})"
                        );
                    }
                }
                // Its errors count the full resolution: no level is exact but where the
                // tile's own samples are all there is.
                assert!(tile.level_errors[0] > 0.0, "level {k} ({tx}, {ty})");
            }
        }
    }
}

#[test]
fn an_open_reads_the_header_and_directory_and_the_top_is_one_contiguous_range() {
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = build_synthetic(dir.path(), Codec::Lz4);
    let reader = ArchiveReader::open(FileSource::open(&path).unwrap()).unwrap();
    let h = reader.header().clone();
    // 4 levels: 4 table offsets; the top's entries are 8 + 5 * 8 bytes each.
    assert_eq!(
        reader.opening_bytes(),
        (HEADER_LEN + 4 * 8 + reader.directory().top.len() * 48 + 4) as u64
    );
    assert_eq!(h.archive_len, std::fs::metadata(&path).unwrap().len());
    let (top, stored) = reader.top().unwrap();
    assert_eq!(stored, h.top_len);
    assert_eq!(top[0].0, reader.pyramid().root());
    let mut at = h.top_offset;
    for (id, tile) in &top {
        let (entry, _) = reader.entry(*id, &CancelToken::new()).unwrap();
        assert_eq!(entry.offset, at, "{id}: the top's tiles follow each other");
        at += entry.stored_len();
        assert_eq!(tile, &reader.tile(*id).unwrap(), "{id}");
    }
    assert_eq!(at, h.top_offset + h.top_len);
    // Every other tile lies in the payloads, none overlapping another.
    let pyramid = reader.pyramid().clone();
    let mut spans = Vec::new();
    for k in 0..pyramid.levels() as u8 {
        let grid = pyramid.grid(k);
        for y in 0..grid.tiles_y() {
            for x in 0..grid.tiles_x() {
                let (e, _) = reader
                    .entry(TileId::at(k, x, y), &CancelToken::new())
                    .unwrap();
                assert!(e.offset >= h.payload_start());
                spans.push((e.offset, e.offset + e.stored_len()));
            }
        }
    }
    spans.sort_unstable();
    assert!(spans.windows(2).all(|w| w[0].1 <= w[1].0));
    assert!(spans.last().unwrap().1 <= h.archive_len);
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
    let west = archive.tile(TileId::new(0, 0)).unwrap().unwrap();
    let east = archive.tile(TileId::new(3, 1)).unwrap().unwrap();
    assert_eq!(west.texture_mips.len(), 6);
    assert!(west.texture_mips[0].iter().all(|&t| t == red));
    assert!(east.texture_mips[0].iter().all(|&t| t == blue));
    assert_eq!(*west.texture_mips[5].first().unwrap(), red);
}
