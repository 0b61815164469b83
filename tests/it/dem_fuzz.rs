//! Property-based fuzzing of every DEM reader with mutated fixtures and random bytes: `Err`,
//! never a panic. `PROPTEST_CASES=100000` runs a long campaign.

use std::path::Path;

use lerc::Precision;
use proptest::prelude::*;
use ruzstd::encoding::{CompressionLevel, compress_to_vec};
use stripmask::db::dem::{self, DemFormat, HeightEncoding, OpenOptions, RawLayout, SampleType};

use crate::support::tiff_writer::{Chunking, Layout, Value, raw, tiff};

fn cases() -> u32 {
    std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(48)
}

const FIXTURES: [(&str, &str); 15] = [
    ("int16_deflate_pred2_nodata.tif", "tif"),
    ("zstd.tif", "tif"),
    ("lerc.tif", "tif"),
    ("scaled.tif", "tif"),
    ("tile.hgt.zip", "hgt.zip"),
    ("uint16_lzw_tiled.tif", "tif"),
    ("int32_packbits.tif", "tif"),
    ("float32_deflate_pred3_tiled_nodata.tif", "tif"),
    ("geographic.tif", "tif"),
    ("uint16.png", "png"),
    ("rgb.png", "png"),
    ("rgb.jpg", "jpg"),
    ("holes.asc", "asc"),
    ("int16_bil.bil", "bil"),
    ("int16_bil.bil", "hgt"),
];

/// The bytes of fixture `name`: a file, or an image made here (`rgb.png`, `rgb.jpg`: a gray
/// ramp in three equal channels; `scaled.tif`: UInt16 decimetres with GDAL's scale and offset;
/// `zstd.tif`, `lerc.tif`: [`codec_tiff`]).
fn fixture(name: &str) -> Vec<u8> {
    if name == "scaled.tif" {
        return scaled_tiff(SCALED);
    }
    if name == "zstd.tif" {
        return codec_tiff(CODECS[1], |b| b);
    }
    if name == "lerc.tif" {
        return codec_tiff(CODECS[2], |b| b);
    }
    if name == "tile.hgt.zip" {
        return zipped_tile();
    }
    let format = match name {
        "rgb.png" => Some(image::ImageFormat::Png),
        "rgb.jpg" => Some(image::ImageFormat::Jpeg),
        _ => None,
    };
    if let Some(format) = format {
        let img = image::RgbImage::from_fn(37, 29, |x, y| image::Rgb([(x * 5 + y) as u8; 3]));
        let mut bytes = std::io::Cursor::new(Vec::new());
        img.write_to(&mut bytes, format).unwrap();
        return bytes.into_inner();
    }
    std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/fixtures")
            .join(name),
    )
    .unwrap()
}

/// A zipped 17 x 17 SRTM tile.
fn zipped_tile() -> Vec<u8> {
    use std::io::Write;
    let mut bytes = std::io::Cursor::new(Vec::new());
    let mut zip = zip::ZipWriter::new(&mut bytes);
    let options = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated);
    zip.start_file("N46W122.hgt", options).unwrap();
    for k in 0..17 * 17i16 {
        zip.write_all(&(k * 3 - 100).to_be_bytes()).unwrap();
    }
    zip.finish().unwrap();
    bytes.into_inner()
}

/// GDAL's metadata of a band of decimetres from -200 m.
const SCALED: &str = "<GDALMetadata><Item name=\"OFFSET\" sample=\"0\" role=\"offset\">-200</Item><Item name=\"SCALE\" sample=\"0\" role=\"scale\">0.1</Item></GDALMetadata>";

/// A 37 x 29 UInt16 TIFF whose GDAL_METADATA tag holds `metadata`.
fn scaled_tiff(metadata: &str) -> Vec<u8> {
    use tiff::encoder::{TiffEncoder, colortype::Gray16};
    let data: Vec<u16> = (0..37 * 29).map(|k| (k * 13 % 40000) as u16).collect();
    let mut bytes = std::io::Cursor::new(Vec::new());
    let mut encoder = TiffEncoder::new(&mut bytes).unwrap();
    let mut image = encoder.new_image::<Gray16>(37, 29).unwrap();
    image
        .encoder()
        .write_tag(tiff::tags::Tag::Unknown(42112), metadata)
        .unwrap();
    image.write_data(&data).unwrap();
    bytes.into_inner()
}

/// The codecs of [`codec_tiff`]: compression, predictor, and the compression around LERC.
const CODECS: [(u16, u16, u32); 5] = [
    (50000, 2, 0),
    (50000, 3, 0),
    (34887, 1, 0),
    (34887, 1, 1),
    (34887, 1, 2),
];

/// A 37 x 29 float32 TIFF in 16 x 16 tiles compressed with `codec` (one of [`CODECS`]), some
/// samples masked in LERC, each tile's stored bytes passed through `garble`.
fn codec_tiff(
    (compression, predictor, wrap): (u16, u16, u32),
    mut garble: impl FnMut(Vec<u8>) -> Vec<u8>,
) -> Vec<u8> {
    let samples: Vec<f32> = (0..37 * 29).map(|k| k as f32 * 0.75 - 100.0).collect();
    let layout = Layout {
        compression,
        predictor,
        tags: vec![(50674, Value::Long(vec![4, wrap]))],
        ..Layout::new(Chunking::Tiles(16, 16))
    };
    let zstd = |b: &[u8]| compress_to_vec(b, CompressionLevel::Fastest);
    tiff((37, 29), &samples, &layout, |s, (w, h)| {
        let bytes = if compression == 50000 {
            zstd(&raw(s, false))
        } else {
            let mut mask = lerc::bitmask::BitMask::all_valid(w * h);
            mask.set_invalid(w + 1);
            let blob = lerc::encode_slice_masked(w as u32, h as u32, s, &mask, Precision::Lossless)
                .unwrap();
            match wrap {
                1 => miniz_oxide::deflate::compress_to_vec_zlib(&blob, 6),
                2 => zstd(&blob),
                _ => blob,
            }
        };
        garble(bytes)
    })
}

/// Opens `bytes` as a file with extension `ext` and reads up to 64 rows.
fn read_some(bytes: &[u8], ext: &str) {
    read_encoded(bytes, ext, HeightEncoding::Gray);
}

/// [`read_some`] with the pixels' height encoding.
fn read_encoded(bytes: &[u8], ext: &str, encoding: HeightEncoding) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(format!("m.{ext}"));
    std::fs::write(&path, bytes).unwrap();
    let raw = RawLayout {
        width: 37,
        height: 29,
        sample_type: SampleType::I16,
        big_endian: false,
        header_bytes: 0,
    };
    let opts = OpenOptions {
        format: if ext == "bil" {
            Some(DemFormat::Raw)
        } else {
            None
        },
        raw: Some(raw),
        nodata: Some(-9999.0),
        encoding,
    };
    if let Ok(mut reader) = dem::open(&path, &opts) {
        let info = reader.info().clone();
        let mut row = vec![0.0; info.width];
        for _ in 0..info.height.min(64) {
            if reader.read_row(&mut row).is_err() {
                return;
            }
            assert!(
                row.iter().all(|v| v.is_finite()),
                "NaN or infinity escaped the fill"
            );
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(cases()))]

    #[test]
    fn mutated_fixtures_never_panic(
        which in 0..FIXTURES.len(),
        edits in proptest::collection::vec((0.0..1.0f64, any::<u8>()), 1..10),
        cut in proptest::option::of(0.0..1.0f64),
    ) {
        let (name, ext) = FIXTURES[which];
        let mut b = fixture(name);
        for (at, v) in edits {
            let i = ((at * b.len() as f64) as usize).min(b.len() - 1);
            b[i] = v;
        }
        if let Some(c) = cut {
            b.truncate((c * b.len() as f64) as usize);
        }
        read_some(&b, ext);
    }

    #[test]
    fn mutated_colour_tiles_read_as_web_map_heights_never_panic(
        encoding in prop::sample::select(vec![HeightEncoding::TerrainRgb, HeightEncoding::Terrarium]),
        edits in proptest::collection::vec((0.0..1.0f64, any::<u8>()), 0..10),
    ) {
        let mut b = fixture("rgb.png");
        for (at, v) in edits {
            let i = ((at * b.len() as f64) as usize).min(b.len() - 1);
            b[i] = v;
        }
        read_encoded(&b, "png", encoding);
    }

    #[test]
    fn random_bytes_never_panic(
        ext in prop::sample::select(vec!["tif", "png", "jpg", "asc", "bil", "hgt"]),
        bytes in proptest::collection::vec(any::<u8>(), 0..600),
    ) {
        read_some(&bytes, ext);
    }

    #[test]
    fn mutated_zstd_and_lerc_chunks_never_panic(
        codec in prop::sample::select(CODECS.to_vec()),
        edits in proptest::collection::vec((0.0..1.0f64, any::<u8>()), 1..10),
        cut in proptest::option::of(0.0..1.0f64),
    ) {
        let b = codec_tiff(codec, |mut chunk| {
            for &(at, v) in &edits {
                let i = ((at * chunk.len() as f64) as usize).min(chunk.len() - 1);
                chunk[i] = v;
            }
            if let Some(c) = cut {
                chunk.truncate((c * chunk.len() as f64) as usize);
            }
            chunk
        });
        read_some(&b, "tif");
    }

    #[test]
    fn random_zstd_and_lerc_chunks_never_panic(
        codec in prop::sample::select(CODECS.to_vec()),
        bytes in proptest::collection::vec(any::<u8>(), 0..600),
    ) {
        // The codec's own first bytes, so that its header is what the random bytes garble.
        let magic: &[u8] = match codec {
            (50000, _, _) | (_, _, 2) => &[0x28, 0xb5, 0x2f, 0xfd],
            (_, _, 1) => &[0x78, 0x9c],
            _ => b"Lerc2 ",
        };
        let b = codec_tiff(codec, |_| [magic, &bytes].concat());
        read_some(&b, "tif");
    }

    #[test]
    fn random_gdal_metadata_never_panics(text in "(<GDALMetadata>|</GDALMetadata>|<Item |role=\"scale\"|role=\"offset\"|sample=\"[0-9]\"|>|</Item>|-?[0-9]{1,5}(\\.[0-9]{1,3})?(e[0-9]{1,3})?|nan|inf|&amp;|[ \n])*") {
        read_some(&scaled_tiff(&text), "tif");
    }

    #[test]
    fn random_ascii_grids_never_panic(text in "(ncols|nrows|cellsize|NODATA_value|xllcorner|-?[0-9]{1,7}(\\.[0-9]{1,3})?|nan|inf|[ \n]){0,60}") {
        read_some(text.as_bytes(), "asc");
    }
}
