//! Bytes per tile and decode time of the payload parts on the Puget Sound tiles: heights and
//! RGB565 textures raw, with LZ4, and the textures as JPEG (quality 85) for comparison.
//! `cargo test --release --test it archive_texture_codecs -- --nocapture` prints the table that
//! docs/database.md quotes.

use std::path::Path;
use std::time::Instant;

use image::ImageEncoder;
use image::codecs::jpeg::JpegEncoder;
use stripmask::db::archive::{ArchiveReader, Codec};
use stripmask::db::builder::{BuildOptions, build};
use stripmask::db::dem::{self, OpenOptions};
use stripmask::db::grid::TileId;
use stripmask::db::rgb565::mip_chain;
use stripmask::db::source::file::FileSource;
use stripmask_raster::rgb565_to_rgb as unpack;

#[test]
fn payload_parts_compress_and_jpeg_textures_decode_to_similar_colours() {
    let dir = tempfile::tempdir().unwrap();
    let input =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/data/puget_sound_1k_height.png");
    let reader = dem::open(&input, &OpenOptions::default()).unwrap();
    let out = dir.path().join("p.smdb");
    let options = BuildOptions {
        spacing: Some(160.0),
        vertical_scale: 0.1,
        codec: Codec::None,
        height_quantum: Some(0.125),
        ..BuildOptions::default()
    };
    build(reader, &out, &options, &|_, _| {}).unwrap();
    let archive = ArchiveReader::open(FileSource::open(&out).unwrap()).unwrap();
    let n = archive.header().tile_count() as usize;
    let (mut h_deflate, mut h_deflate1, mut t_deflate) = (0, 0, 0);
    let mut deflate_secs = 0.0;
    let (mut h_raw, mut h_lz4, mut h_planes, mut t_raw, mut t_lz4, mut t_jpeg) = (0, 0, 0, 0, 0, 0);
    let (mut lz4_secs, mut jpeg_secs) = (0.0, 0.0);
    let mut worst_channel_error = 0i32;
    for ty in 0..8 {
        for tx in 0..8 {
            let tile = archive.tile(TileId::new(tx, ty)).unwrap().unwrap();
            let mut deltas = Vec::new();
            for row in tile.heights.chunks_exact(tile.tile_size) {
                let mut prev = 0u16;
                for &q in row {
                    deltas.push(q.wrapping_sub(prev));
                    prev = q;
                }
            }
            let heights: Vec<u8> = deltas.iter().flat_map(|q| q.to_le_bytes()).collect();
            let planes: Vec<u8> = deltas
                .iter()
                .map(|q| (q & 0xff) as u8)
                .chain(deltas.iter().map(|q| (q >> 8) as u8))
                .collect();
            h_planes += lz4_flex::block::compress(&planes).len();
            let zz: Vec<u16> = deltas
                .iter()
                .map(|&d| {
                    let d = d as i16;
                    ((d << 1) ^ (d >> 15)) as u16
                })
                .collect();
            let zplanes: Vec<u8> = zz
                .iter()
                .map(|q| (q & 0xff) as u8)
                .chain(zz.iter().map(|q| (q >> 8) as u8))
                .collect();
            h_deflate += miniz_oxide::deflate::compress_to_vec(&zplanes, 6).len();
            h_deflate1 += miniz_oxide::deflate::compress_to_vec(&zplanes, 1).len();
            let texture: Vec<u8> = tile
                .texture_mips
                .iter()
                .flatten()
                .flat_map(|t| t.to_le_bytes())
                .collect();
            h_raw += heights.len();
            h_lz4 += lz4_flex::block::compress(&heights).len();
            t_raw += texture.len();
            let packed = lz4_flex::block::compress(&texture);
            t_lz4 += packed.len();
            let d = miniz_oxide::deflate::compress_to_vec(&texture, 6);
            t_deflate += d.len();
            let t = Instant::now();
            let _ = miniz_oxide::inflate::decompress_to_vec(&d).unwrap();
            deflate_secs += t.elapsed().as_secs_f64();
            let t = Instant::now();
            let back = lz4_flex::block::decompress(&packed, texture.len()).unwrap();
            lz4_secs += t.elapsed().as_secs_f64();
            assert_eq!(back, texture);

            let size = tile.texture_size;
            let rgb: Vec<u8> = tile.texture_mips[0]
                .iter()
                .flat_map(|&t| unpack(t))
                .collect();
            let mut jpeg = Vec::new();
            JpegEncoder::new_with_quality(&mut jpeg, 85)
                .write_image(
                    &rgb,
                    size as u32,
                    size as u32,
                    image::ExtendedColorType::Rgb8,
                )
                .unwrap();
            t_jpeg += jpeg.len();
            // A JPEG client decodes, then builds the mip chain and packs RGB565 itself.
            let t = Instant::now();
            let decoded = image::load_from_memory_with_format(&jpeg, image::ImageFormat::Jpeg)
                .unwrap()
                .to_rgb8();
            let texels: Vec<[u8; 3]> = decoded.pixels().map(|p| p.0).collect();
            let mips = mip_chain(&texels, size);
            jpeg_secs += t.elapsed().as_secs_f64();
            assert_eq!(mips.len(), tile.texture_mips.len());
            for (a, b) in texels.iter().zip(&tile.texture_mips[0]) {
                let b = unpack(*b);
                for k in 0..3 {
                    worst_channel_error =
                        worst_channel_error.max((i32::from(a[k]) - i32::from(b[k])).abs());
                }
            }
        }
    }
    let per = |b: usize| b as f64 / n as f64 / 1024.0;
    println!("per tile over {n} Puget Sound tiles (129 samples, 128 texels):");
    println!(
        "  heights u16 delta-coded   raw {:6.1} KiB  lz4 {:6.1} KiB  byte planes + lz4 {:6.1} KiB",
        per(h_raw),
        per(h_lz4),
        per(h_planes)
    );
    println!(
        "  texture RGB565 + mips     raw {:6.1} KiB  lz4 {:6.1} KiB  decode {:.3} ms",
        per(t_raw),
        per(t_lz4),
        lz4_secs * 1e3 / n as f64
    );
    println!(
        "  texture JPEG q85 level 0      {:6.1} KiB  decode + mips {:.3} ms, worst channel error {worst_channel_error}",
        per(t_jpeg),
        jpeg_secs * 1e3 / n as f64
    );
    println!(
        "  deflate: heights zigzag planes l6 {:6.1} l1 {:6.1}; texture l6 {:6.1} KiB, inflate {:.3} ms",
        per(h_deflate),
        per(h_deflate1),
        per(t_deflate),
        deflate_secs * 1e3 / n as f64
    );
    assert!(h_lz4 < h_raw && t_lz4 <= t_raw + t_raw / 100);
    assert!(t_jpeg < t_lz4);
}
