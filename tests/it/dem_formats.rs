//! Every DEM reader against fixtures written by GDAL, and a build/read round trip per format.

use std::path::{Path, PathBuf};
use stripmask::db::grid::TileId;

use crate::support::tiff_writer::{
    Chunking, Layout, Sample, Tags, Value, raw, tiff, write_geotiff,
};
use stripmask::db::archive::ArchiveReader;
use stripmask::db::builder::{BuildOptions, build, build_file};
use stripmask::db::dem::{self, DemFormat, OpenOptions, RawLayout, SampleType};
use stripmask::db::source::file::FileSource;

const W: usize = 37;
const H: usize = 29;

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

fn truth(i: usize, j: usize) -> f32 {
    (100 + 7 * i + 3 * j + (i * j) % 11) as f32
}

/// Whether sample `(i, j)` is one of the fixtures' holes: columns 3..=6 of rows 2..=4.
fn hole(i: usize, j: usize) -> bool {
    (2..5).contains(&j) && (3..7).contains(&i)
}

/// The expected value after the nodata fill: a hole takes the nearest valid sample in 2-D; on a
/// tie, the one in the nearer row, above before below, then left before right.
fn filled(i: usize, j: usize, holes: bool) -> f32 {
    if !(holes && hole(i, j)) {
        return truth(i, j);
    }
    let mut best = (usize::MAX, 0.0);
    for dk in 0..H {
        for k in [j.checked_sub(dk), Some(j + dk).filter(|_| dk > 0)]
            .into_iter()
            .flatten()
            .filter(|&k| k < H)
        {
            for dx in 0..W {
                for c in [i.checked_sub(dx), Some(i + dx).filter(|_| dx > 0)]
                    .into_iter()
                    .flatten()
                    .filter(|&c| c < W && !hole(c, k))
                {
                    let d = dk * dk + dx * dx;
                    if d < best.0 {
                        best = (d, truth(c, k));
                    }
                }
            }
        }
    }
    best.1
}

fn options() -> OpenOptions {
    OpenOptions::default()
}

/// Reads `path` and compares every sample with the truth (filled where the fixture has holes).
fn check_samples(path: &Path, opts: &OpenOptions, holes: bool) {
    let dem = dem::open(path, opts).unwrap().read_all().unwrap();
    assert_eq!((dem.width, dem.height), (W, H), "{}", path.display());
    for j in 0..H {
        for i in 0..W {
            assert_eq!(
                dem.at(i, j),
                filled(i, j, holes),
                "{} ({i}, {j})",
                path.display()
            );
        }
    }
}

/// [`check_samples`], then builds an archive with 17-sample tiles and reads every sample back.
fn check(path: &Path, opts: &OpenOptions, holes: bool) {
    check_samples(path, opts, holes);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("t.smdb");
    let build_opts = BuildOptions {
        tile_size: 17,
        ..BuildOptions::default()
    };
    let reader = dem::open(path, opts).unwrap();
    build(reader, &out, &build_opts, &|_, _| {}).unwrap();
    let archive = ArchiveReader::open(FileSource::open(&out).unwrap()).unwrap();
    let h = archive.header();
    assert_eq!((h.tiles_x, h.tiles_y), (3, 2));
    for ty in 0..2 {
        for tx in 0..3 {
            let tile = archive
                .tile(TileId::new(tx as u32, ty as u32))
                .unwrap()
                .unwrap();
            for j in 0..17 {
                for i in 0..17 {
                    let (gi, gj) = ((tx * 16 + i).min(W - 1), (ty * 16 + j).min(H - 1));
                    let want = filled(gi, gj, holes);
                    assert!((tile.height(i, j) - want).abs() <= tile.quantum * 0.5 + 1e-3);
                }
            }
        }
    }
}

#[test]
fn geotiff_int16_deflate_predictor_strips_with_nodata() {
    let path = fixture("int16_deflate_pred2_nodata.tif");
    check(&path, &options(), true);
    let info = dem::open(&path, &options()).unwrap().info().clone();
    assert_eq!(info.spacing_hint, Some(30.0));
    assert_eq!(info.origin_hint, Some((500_015.0, 4_000_855.0)));
}

#[test]
fn geotiff_uint16_lzw_tiled() {
    check(&fixture("uint16_lzw_tiled.tif"), &options(), false);
}

#[test]
fn geotiff_int32_packbits() {
    check(&fixture("int32_packbits.tif"), &options(), false);
}

#[test]
fn geotiff_float32_deflate_float_predictor_tiled_with_nodata() {
    check(
        &fixture("float32_deflate_pred3_tiled_nodata.tif"),
        &options(),
        true,
    );
}

#[test]
fn png_sixteen_bit_grayscale() {
    check(&fixture("uint16.png"), &options(), false);
}

#[test]
fn esri_ascii_grids_ours_and_gdals() {
    check(&fixture("holes.asc"), &options(), true);
    check(&fixture("gdal_holes.asc"), &options(), true);
    check(&fixture("plain.asc"), &options(), false);
    let info = dem::open(&fixture("plain.asc"), &options())
        .unwrap()
        .info()
        .clone();
    assert_eq!(info.spacing_hint, Some(30.0));
    assert_eq!(info.origin_hint, Some((500_015.0, 4_000_855.0)));
}

#[test]
fn bil_with_explicit_layout_and_nodata_option() {
    let opts = OpenOptions {
        format: None,
        raw: Some(RawLayout {
            width: W,
            height: H,
            sample_type: SampleType::I16,
            big_endian: false,
            header_bytes: 0,
        }),
        nodata: Some(-9999.0),
        ..OpenOptions::default()
    };
    check(&fixture("int16_bil.bil"), &opts, true);
}

#[test]
fn srtm_hgt_with_voids() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("N47W122.hgt");
    let side = 33;
    let mut bytes = Vec::new();
    for j in 0..side {
        for i in 0..side {
            let v: i16 = if (i, j) == (5, 5) {
                -32768
            } else {
                (i * 10 + j) as i16 - 50
            };
            bytes.extend_from_slice(&v.to_be_bytes());
        }
    }
    std::fs::write(&path, bytes).unwrap();
    let dem = dem::open(&path, &options()).unwrap().read_all().unwrap();
    assert_eq!((dem.width, dem.height), (33, 33));
    assert_eq!(dem.at(0, 0), -50.0);
    assert_eq!(dem.at(32, 1), 32.0 * 10.0 + 1.0 - 50.0);
    // The void takes its left neighbour (a tie between columns 4 and 6).
    assert_eq!(dem.at(5, 5), dem.at(4, 5));
}

#[test]
fn geographic_geotiff_gets_metres_on_both_axes() {
    let path = fixture("geographic.tif");
    check_samples(&path, &options(), false);
    let info = dem::open(&path, &options()).unwrap().info().clone();
    // 1/29 degree of latitude per row, 1/37 degree of longitude per column, centred at 47°N.
    let spacing = info.spacing_hint.unwrap();
    assert!((spacing - 111_320.0 / 29.0).abs() < 1e-6, "{spacing}");
    let cos = 47f64.to_radians().cos();
    let scale = info.east_west_scale;
    assert!((scale - 29.0 / 37.0 * cos).abs() < 1e-9, "{scale}");
    let (x, y) = info.origin_hint.unwrap();
    assert!((y - (47.5 - 0.5 / 29.0) * 111_320.0).abs() < 1e-6, "{y}");
    assert!(
        (x - (-122.5 + 0.5 / 37.0) * 111_320.0 * cos).abs() < 1e-6,
        "{x}"
    );
}

#[test]
fn eight_bit_png_and_big_endian_raw() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("eight.png");
    image::GrayImage::from_fn(5, 4, |x, y| image::Luma([(x * 10 + y) as u8]))
        .save(&png)
        .unwrap();
    let dem = dem::open(&png, &options()).unwrap().read_all().unwrap();
    assert_eq!((dem.width, dem.height), (5, 4));
    assert_eq!(dem.at(4, 3), 43.0);

    let raw = dir.path().join("be.r32");
    let mut bytes = vec![0u8; 8];
    for k in 0..6 {
        bytes.extend_from_slice(&(k as f32 * 1.5 - 2.0).to_be_bytes());
    }
    std::fs::write(&raw, bytes).unwrap();
    let opts = OpenOptions {
        format: None,
        raw: Some(RawLayout {
            width: 3,
            height: 2,
            sample_type: SampleType::F32,
            big_endian: true,
            header_bytes: 8,
        }),
        nodata: None,
        ..OpenOptions::default()
    };
    let dem = dem::open(&raw, &opts).unwrap().read_all().unwrap();
    assert_eq!(dem.samples, vec![-2.0, -0.5, 1.0, 2.5, 4.0, 5.5]);
}

#[test]
fn bad_inputs_name_the_file_and_the_problem() {
    let dir = tempfile::tempdir().unwrap();
    let err = |path: &Path, opts: &OpenOptions| -> String {
        match dem::open(path, opts).and_then(|r| r.read_all()) {
            Ok(_) => panic!("{} read", path.display()),
            Err(e) => e.to_string(),
        }
    };

    let e = err(&fixture("rgb_byte.tif"), &options());
    assert!(
        e.contains("rgb_byte.tif") && e.contains("unsupported TIFF sample layout"),
        "{e}"
    );

    // A truncated GeoTIFF: the strips point past the end of the file.
    let bytes = std::fs::read(fixture("int32_packbits.tif")).unwrap();
    let cut = dir.path().join("cut.tif");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let e = err(&cut, &options());
    assert!(e.contains("cut.tif"), "{e}");

    // A truncated PNG.
    let bytes = std::fs::read(fixture("uint16.png")).unwrap();
    let cut = dir.path().join("cut.png");
    std::fs::write(&cut, &bytes[..bytes.len() - 40]).unwrap();
    let e = err(&cut, &options());
    assert!(e.contains("cut.png"), "{e}");

    // Raw with wrong dimensions.
    let raw = RawLayout {
        width: 40,
        height: H,
        sample_type: SampleType::I16,
        big_endian: false,
        header_bytes: 0,
    };
    let opts = OpenOptions {
        format: Some(DemFormat::Raw),
        raw: Some(raw),
        nodata: None,
        ..OpenOptions::default()
    };
    let e = err(&fixture("int16_bil.bil"), &opts);
    assert!(
        e.contains("int16_bil.bil") && e.contains("2146 bytes"),
        "{e}"
    );

    // An .hgt that is not square.
    let hgt = dir.path().join("odd.hgt");
    std::fs::write(&hgt, vec![0u8; 2 * 30]).unwrap();
    let e = err(&hgt, &options());
    assert!(e.contains("odd.hgt") && e.contains("square"), "{e}");

    // An ASCII grid that ends early, and one with a bad number.
    let text = std::fs::read_to_string(fixture("plain.asc")).unwrap();
    let short = dir.path().join("short.asc");
    std::fs::write(&short, &text[..text.len() / 2]).unwrap();
    let e = err(&short, &options());
    assert!(e.contains("short.asc") && e.contains("ends at row"), "{e}");
    let bad = dir.path().join("bad.asc");
    std::fs::write(&bad, text.replacen(" 107 ", " 1o7 ", 1)).unwrap();
    let e = err(&bad, &options());
    assert!(e.contains("bad.asc") && e.contains("not a number"), "{e}");

    // Unknown extension.
    let e = err(&dir.path().join("x.dat"), &options());
    assert!(e.contains("x.dat") && e.contains("--format"), "{e}");
}

/// Writes a UInt16 GeoTIFF of `w x h` samples `raw(i, j)` with `tags`.
fn write_u16_tiff(path: &Path, size: (u32, u32), raw: impl Fn(u32, u32) -> u16, tags: &Tags) {
    write_geotiff::<tiff::encoder::colortype::Gray16>(path, size, raw, tags);
}

#[test]
fn geotiff_with_gdal_scale_and_offset_gives_metres_and_compares_nodata_raw() {
    // How GDAL stores decimetres from -200 m in UInt16: raw 0 is -200 m, raw 65535 nodata.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("decimetres.tif");
    let metadata = "<GDALMetadata>\n  <Item name=\"OFFSET\" sample=\"0\" role=\"offset\">-200</Item>\n  <Item name=\"SCALE\" sample=\"0\" role=\"scale\">0.1</Item>\n</GDALMetadata>\n";
    let raw = |i: u32, j: u32| {
        if (i, j) == (3, 4) {
            65535
        } else {
            (i * 100 + j * 7) as u16
        }
    };
    let tags = Tags {
        metadata: Some(metadata),
        nodata: Some("65535"),
        ..Tags::default()
    };
    write_u16_tiff(&path, (40, 30), raw, &tags);
    let reader = dem::open(&path, &options()).unwrap();
    assert!(
        reader
            .info()
            .notes
            .iter()
            .any(|n| n.contains("scale 0.1 and offset -200")),
        "{:?}",
        reader.info().notes
    );
    let dem = reader.read_all().unwrap();
    assert_eq!(dem.at(0, 0), -200.0);
    assert!((dem.at(39, 29) - (0.1 * f32::from(raw(39, 29)) - 200.0)).abs() < 1e-3);
    // The nodata sample took a neighbour's height, not 65535 * 0.1 - 200.
    assert!(dem.at(3, 4) < 200.0, "{}", dem.at(3, 4));
}

#[test]
fn geotiff_whose_gdal_metadata_is_not_xml_is_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("garbled.tif");
    let tags = Tags {
        metadata: Some("<GDALMetadata><Item role="),
        ..Tags::default()
    };
    write_u16_tiff(&path, (8, 8), |i, j| (i + j) as u16, &tags);
    let e = dem::open(&path, &options()).err().unwrap().to_string();
    assert!(
        e.contains("garbled.tif") && e.contains("GDAL_METADATA"),
        "{e}"
    );
}

/// A projected GeoTIFF of 20 x 10 samples, raw value `100 + i`, with `keys` and cells of
/// `cell` file units whose first corner lies at `corner`; what the reader makes of it.
fn projected(keys: &[(u16, u16)], cell: [f64; 2], corner: [f64; 2]) -> (dem::DemInfo, dem::Dem) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("projected.tif");
    let tags = Tags {
        georeference: Some((cell, corner)),
        keys,
        ..Tags::default()
    };
    write_u16_tiff(&path, (20, 10), |i, _| 100 + i as u16, &tags);
    let reader = dem::open(&path, &options()).unwrap();
    let info = reader.info().clone();
    (info, reader.read_all().unwrap())
}

#[test]
fn a_projected_grid_in_us_survey_feet_gets_metres_never_feet_taken_as_metres() {
    // A state plane grid (EPSG:2926) of 3 ft cells, heights in feet.
    let keys = [(1024, 1), (3072, 2926), (3076, 9003), (4099, 9003)];
    let (info, dem) = projected(&keys, [3.0, 3.0], [1_000_000.0, 500_000.0]);
    let foot = 1200.0 / 3937.0;
    assert!(
        (info.spacing_hint.unwrap() - 3.0 * foot).abs() < 1e-9,
        "{info:?}"
    );
    let (x, y) = info.origin_hint.unwrap();
    assert!((x - 1_000_001.5 * foot).abs() < 1e-6 && (y - 499_998.5 * foot).abs() < 1e-6);
    assert!(
        (dem.at(0, 0) - 100.0 * foot as f32).abs() < 1e-3,
        "{}",
        dem.at(0, 0)
    );
    let notes = info.notes.join("\n");
    assert!(notes.contains("EPSG:2926 in US survey feet"), "{notes}");
    assert!(notes.contains("heights in US survey feet"), "{notes}");
}

#[test]
fn web_mercator_metres_become_ground_metres_at_the_grid_latitude() {
    // 30 m Web Mercator cells around 46.85° N (northing 5,918,000).
    let keys = [(1024, 1), (3072, 3857), (3076, 9001)];
    let (info, _) = projected(&keys, [30.0, 30.0], [-13_500_000.0, 5_918_150.0]);
    let latitude = (5_918_000.0f64 / 6_378_137.0).sinh().atan();
    let spacing = info.spacing_hint.unwrap();
    assert!((spacing - 30.0 * latitude.cos()).abs() < 0.01, "{spacing}");
    assert!(
        info.notes.iter().any(|n| n.contains("Web Mercator")),
        "{:?}",
        info.notes
    );
}

#[test]
fn a_projected_grid_in_an_unknown_unit_asks_for_the_spacing() {
    let keys = [(1024, 1), (3072, 32610), (3076, 9036)];
    let (info, _) = projected(&keys, [0.03, 0.03], [500.0, 5000.0]);
    let problem = info.spacing_problem.expect("no spacing problem");
    assert!(
        problem.contains("9036") && problem.contains("--spacing"),
        "{problem}"
    );
}

#[test]
fn a_projected_grid_of_oblong_cells_is_resampled_to_square_ones() {
    let keys = [(1024, 1), (3072, 32610), (3076, 9001)];
    let (info, _) = projected(&keys, [20.0, 30.0], [500_000.0, 5_000_000.0]);
    assert_eq!(info.spacing_hint, Some(30.0));
    assert!((info.east_west_scale - 2.0 / 3.0).abs() < 1e-12);
}

/// Writes an RGB PNG of `w x h` pixels `rgb(i, j)`.
fn write_rgb_png(path: &Path, (w, h): (u32, u32), rgb: impl Fn(u32, u32) -> [u8; 3]) {
    image::RgbImage::from_fn(w, h, |i, j| image::Rgb(rgb(i, j)))
        .save(path)
        .unwrap();
}

#[test]
fn terrain_rgb_and_terrarium_tiles_decode_to_metres() {
    use stripmask::db::dem::HeightEncoding;
    let dir = tempfile::tempdir().unwrap();
    // Terrain-RGB: 0 m is 100,000 tenths, (1, 134, 160); Rainier's 4,392 m is (2, 50, 48).
    let path = dir.path().join("terrain-rgb.png");
    write_rgb_png(&path, (20, 10), |i, _| {
        if i < 10 { [1, 134, 160] } else { [2, 50, 48] }
    });
    let opts = OpenOptions {
        encoding: HeightEncoding::TerrainRgb,
        ..OpenOptions::default()
    };
    let reader = dem::open(&path, &opts).unwrap();
    assert!(
        reader
            .info()
            .notes
            .iter()
            .any(|n| n.contains("terrain-rgb")),
        "{:?}",
        reader.info().notes
    );
    let dem = reader.read_all().unwrap();
    assert!((dem.at(0, 0) - 0.0).abs() < 1e-3, "{}", dem.at(0, 0));
    assert!((dem.at(19, 9) - 4392.0).abs() < 1e-2, "{}", dem.at(19, 9));
    // Terrarium: -10.5 m below the sea is (127, 245, 128).
    let path = dir.path().join("terrarium.png");
    write_rgb_png(&path, (4, 4), |_, _| [127, 245, 128]);
    let opts = OpenOptions {
        encoding: HeightEncoding::Terrarium,
        ..OpenOptions::default()
    };
    let dem = dem::open(&path, &opts).unwrap().read_all().unwrap();
    assert_eq!(dem.at(2, 2), -10.5);
    // The same colour tile read as gray is refused, naming a pixel.
    let e = dem::open(&path, &options())
        .unwrap()
        .read_all()
        .err()
        .unwrap();
    assert!(e.to_string().contains("colour image"), "{e}");
}

#[test]
fn an_encoding_on_a_gray_png_or_another_format_is_refused_by_name() {
    use stripmask::db::dem::HeightEncoding;
    let opts = OpenOptions {
        encoding: HeightEncoding::TerrainRgb,
        ..OpenOptions::default()
    };
    let e = dem::open(&fixture("uint16.png"), &opts)
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("uint16.png") && e.contains("8-bit red, green and blue"),
        "{e}"
    );
    let e = dem::open(&fixture("uint16_lzw_tiled.tif"), &opts)
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("uint16_lzw_tiled.tif") && e.contains("for PNG"),
        "{e}"
    );
}

/// The bytes of a 33 x 33 SRTM tile: `(i * 10 + j) - 50` metres.
fn hgt_bytes() -> Vec<u8> {
    (0..33 * 33)
        .flat_map(|k: i16| ((k % 33) * 10 + k / 33 - 50).to_be_bytes())
        .collect()
}

/// Writes a zip holding `entries` (name, bytes), DEFLATE-compressed.
fn write_zip(path: &Path, entries: &[(&str, &[u8])]) {
    use std::io::Write;
    let mut zip = zip::ZipWriter::new(std::fs::File::create(path).unwrap());
    let options = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated);
    for (name, bytes) in entries {
        zip.start_file(*name, options).unwrap();
        zip.write_all(bytes).unwrap();
    }
    zip.finish().unwrap();
}

#[test]
fn a_zipped_srtm_tile_reads_as_its_hgt_and_is_placed_by_its_name() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = hgt_bytes();
    let plain = dir.path().join("N46W122.hgt");
    std::fs::write(&plain, &bytes).unwrap();
    let zipped = dir.path().join("N46W122.SRTMGL1.hgt.zip");
    write_zip(&zipped, &[("N46W122.hgt", &bytes)]);
    let a = dem::open(&plain, &options()).unwrap();
    let b = dem::open(&zipped, &options()).unwrap();
    assert_eq!(a.info().spacing_hint, b.info().spacing_hint);
    assert_eq!(a.info().origin_hint, b.info().origin_hint);
    assert!(b.info().origin_hint.is_some());
    let (a, b) = (a.read_all().unwrap(), b.read_all().unwrap());
    assert_eq!(a.samples, b.samples);
    assert_eq!(b.at(32, 1), 32.0 * 10.0 + 1.0 - 50.0);
}

#[test]
fn a_zip_without_one_tile_or_with_a_short_one_is_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let two = dir.path().join("two.hgt.zip");
    write_zip(&two, &[("N1E1.hgt", &[0; 8]), ("N2E2.hgt", &[0; 8])]);
    let e = dem::open(&two, &options()).err().unwrap().to_string();
    assert!(e.contains("two.hgt.zip") && e.contains("holds 2"), "{e}");
    let odd = dir.path().join("N46W122.hgt.zip");
    write_zip(&odd, &[("N46W122.hgt", &[0; 7])]);
    let e = dem::open(&odd, &options()).err().unwrap().to_string();
    assert!(
        e.contains("N46W122.hgt.zip") && e.contains("not a square"),
        "{e}"
    );
    let garbage = dir.path().join("N46W122.SRTMGL1.hgt.zip");
    std::fs::write(&garbage, b"PK\x03\x04 not really").unwrap();
    let e = dem::open(&garbage, &options()).err().unwrap().to_string();
    assert!(e.contains("not a readable zip"), "{e}");
}

/// Sets the byte count (and offset) of strip `strip` of the little-endian TIFF at `path` to 0,
/// as GDAL's sparse files store a strip that is all nodata.
fn empty_strip(path: &Path, strip: usize) {
    let mut b = std::fs::read(path).unwrap();
    let u16_at = |b: &[u8], at: usize| u16::from_le_bytes([b[at], b[at + 1]]);
    let u32_at = |b: &[u8], at: usize| u32::from_le_bytes(b[at..at + 4].try_into().unwrap());
    assert_eq!(&b[..4], b"II*\0");
    let ifd = u32_at(&b, 4) as usize;
    for e in 0..usize::from(u16_at(&b, ifd)) {
        let entry = ifd + 2 + 12 * e;
        if matches!(u16_at(&b, entry), 273 | 279) {
            let size = if u16_at(&b, entry + 2) == 3 { 2 } else { 4 };
            let at = u32_at(&b, entry + 8) as usize + strip * size;
            b[at..at + size].fill(0);
        }
    }
    std::fs::write(path, b).unwrap();
}

#[test]
fn a_sparse_geotiff_reads_its_empty_strips_as_nodata() {
    use tiff::encoder::{TiffEncoder, colortype::Gray16};
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sparse.tif");
    let (w, h) = (16u32, 12u32);
    let data: Vec<u16> = (0..w * h).map(|k| 100 + (k % w) as u16).collect();
    let mut encoder = TiffEncoder::new(std::fs::File::create(&path).unwrap()).unwrap();
    let mut image = encoder.new_image::<Gray16>(w, h).unwrap();
    image.rows_per_strip(4).unwrap();
    image.write_data(&data).unwrap();
    drop(encoder);
    empty_strip(&path, 2);
    let dem = dem::open(&path, &options()).unwrap().read_all().unwrap();
    // Rows 8 .. 12 had no bytes: nodata, filled from the rows above.
    assert_eq!(dem.at(5, 3), 105.0);
    assert_eq!(dem.at(5, 11), dem.at(5, 7));
}

/// The truth grid as samples of `T`, the fixtures' holes `nodata` when given.
fn truth_grid<T: Copy>(nodata: Option<T>, sample: impl Fn(f32) -> T) -> Vec<T> {
    (0..W * H)
        .map(|k| match nodata {
            Some(n) if hole(k % W, k / W) => n,
            _ => sample(truth(k % W, k / W)),
        })
        .collect()
}

/// The stored bytes of a chunk `width` samples wide after the horizontal predictor: each sample
/// less the one before it in its row (`sub`, wrapping), in the file's byte order.
fn horizontal_differences<T: Sample>(
    samples: &[T],
    width: usize,
    sub: fn(T, T) -> T,
    big_endian: bool,
) -> Vec<u8> {
    let differences: Vec<T> = samples
        .chunks(width)
        .flat_map(|row| {
            (0..row.len()).map(|k| {
                if k == 0 {
                    row[0]
                } else {
                    sub(row[k], row[k - 1])
                }
            })
        })
        .collect();
    raw(&differences, big_endian)
}

/// The stored bytes of a chunk of `f32` samples `width` wide after the floating-point predictor
/// (libtiff's `fpDiff`): per row, the samples' bytes regrouped into planes, most significant
/// first, then each byte less the one before it.
fn float_differences(samples: &[f32], width: usize) -> Vec<u8> {
    samples
        .chunks(width)
        .flat_map(|row| {
            let mut planes: Vec<u8> = (0..4)
                .flat_map(|p| row.iter().map(move |x| x.to_be_bytes()[p]))
                .collect();
            for i in (1..planes.len()).rev() {
                planes[i] = planes[i].wrapping_sub(planes[i - 1]);
            }
            planes
        })
        .collect()
}

/// ZSTD of `bytes`.
fn zstd(bytes: &[u8]) -> Vec<u8> {
    ruzstd::encoding::compress_to_vec(bytes, ruzstd::encoding::CompressionLevel::Fastest)
}

/// A lossless LERC blob of `width x rows` samples; `valid(k)` says whether sample `k` is.
fn lerc_blob<T: lerc::Sample>(
    samples: &[T],
    (width, rows): (usize, usize),
    valid: impl Fn(usize) -> bool,
) -> Vec<u8> {
    let mut mask = lerc::bitmask::BitMask::all_valid(samples.len());
    for k in (0..samples.len()).filter(|&k| !valid(k)) {
        mask.set_invalid(k);
    }
    lerc::encode_slice_masked(
        width as u32,
        rows as u32,
        samples,
        &mask,
        lerc::Precision::Lossless,
    )
    .unwrap()
}

/// Writes `samples` (a `W x H` grid) to `dir/name` as `layout` says, each chunk stored by
/// `store`, and beside it the same grid uncompressed with the same tags and byte order; their
/// paths.
fn write_pair<T: Sample>(
    dir: &Path,
    name: &str,
    samples: &[T],
    layout: &Layout,
    store: impl FnMut(&[T], (usize, usize)) -> Vec<u8>,
) -> (PathBuf, PathBuf) {
    let size = (W as u32, H as u32);
    let path = dir.join(name);
    std::fs::write(&path, tiff(size, samples, layout, store)).unwrap();
    let plain_layout = Layout {
        compression: 1,
        predictor: 1,
        tags: layout
            .tags
            .iter()
            .filter(|(tag, _)| *tag != LERC_PARAMETERS)
            .cloned()
            .collect(),
        ..layout.clone()
    };
    let plain = dir.join(format!("plain_{name}"));
    let be = layout.big_endian;
    std::fs::write(
        &plain,
        tiff(size, samples, &plain_layout, |s, _| raw(s, be)),
    )
    .unwrap();
    (path, plain)
}

/// Asserts that `path` reads to exactly the samples of its uncompressed twin `plain`.
fn reads_like(path: &Path, plain: &Path) {
    let a = dem::open(path, &options()).unwrap().read_all().unwrap();
    let b = dem::open(plain, &options()).unwrap().read_all().unwrap();
    assert_eq!((a.width, a.height), (b.width, b.height));
    assert!(
        a.samples
            .iter()
            .zip(&b.samples)
            .all(|(x, y)| x.to_bits() == y.to_bits()),
        "{} reads unlike {}",
        path.display(),
        plain.display()
    );
}

/// Asserts that `path` and its uncompressed twin `plain` build to the same archive bytes.
fn builds_like(path: &Path, plain: &Path) {
    let dir = tempfile::tempdir().unwrap();
    let options = BuildOptions {
        tile_size: 17,
        ..BuildOptions::default()
    };
    let archives: Vec<Vec<u8>> = [path, plain]
        .iter()
        .map(|p| {
            let out = dir.path().join("out.smdb");
            build_file(p, &OpenOptions::default(), &out, &options, &|_, _| {}).unwrap();
            std::fs::read(&out).unwrap()
        })
        .collect();
    assert!(
        archives[0] == archives[1],
        "{} builds unlike its twin",
        path.display()
    );
}

/// GDAL's nodata tag holding -9999.
fn nodata_tag() -> (u16, Value) {
    (42113, Value::Ascii("-9999".into()))
}

/// The TIFF tag of LERC's version and additional compression.
const LERC_PARAMETERS: u16 = 50674;

#[test]
fn geotiff_zstd_float32_float_predictor_tiled_with_nodata() {
    let dir = tempfile::tempdir().unwrap();
    let layout = Layout {
        compression: 50000,
        predictor: 3,
        tags: vec![nodata_tag()],
        ..Layout::new(Chunking::Tiles(16, 16))
    };
    let store = |s: &[f32], (w, _): (usize, usize)| zstd(&float_differences(s, w));
    let grid = truth_grid(Some(-9999.0), |v| v);
    let (path, plain) = write_pair(dir.path(), "zstd_f32.tif", &grid, &layout, store);
    check(&path, &options(), true);
    reads_like(&path, &plain);
    builds_like(&path, &plain);
    // Fractions and signs exercise every byte plane.
    let fractions: Vec<f32> = (0..W * H)
        .map(|k| (k as f32 * 0.37 - 200.0) * if k % 3 == 0 { -1.0 } else { 1.0 })
        .collect();
    let (path, plain) = write_pair(dir.path(), "zstd_frac.tif", &fractions, &layout, store);
    reads_like(&path, &plain);
}

#[test]
fn geotiff_zstd_int16_horizontal_predictor_strips_with_nodata() {
    let dir = tempfile::tempdir().unwrap();
    let layout = Layout {
        compression: 50000,
        predictor: 2,
        tags: vec![nodata_tag()],
        ..Layout::new(Chunking::Strips(5))
    };
    let store = |s: &[i16], (w, _): (usize, usize)| {
        zstd(&horizontal_differences(s, w, i16::wrapping_sub, false))
    };
    let grid = truth_grid(Some(-9999), |v| v as i16);
    let (path, plain) = write_pair(dir.path(), "zstd_i16.tif", &grid, &layout, store);
    check(&path, &options(), true);
    reads_like(&path, &plain);
    // Differences that wrap.
    let wrapping: Vec<i16> = (0..W * H)
        .map(|k| {
            if k % 2 == 0 {
                30_000
            } else {
                -30_000 + k as i16
            }
        })
        .collect();
    let (path, plain) = write_pair(dir.path(), "zstd_wrap.tif", &wrapping, &layout, store);
    reads_like(&path, &plain);
}

#[test]
fn geotiff_zstd_big_endian() {
    let dir = tempfile::tempdir().unwrap();
    let big = |compression, predictor, chunking| Layout {
        big_endian: true,
        compression,
        predictor,
        ..Layout::new(chunking)
    };
    let layout = big(50000, 2, Chunking::Tiles(16, 16));
    let store = |s: &[u16], (w, _): (usize, usize)| {
        zstd(&horizontal_differences(s, w, u16::wrapping_sub, true))
    };
    let grid = truth_grid(None, |v| v as u16);
    let (path, plain) = write_pair(dir.path(), "be_u16.tif", &grid, &layout, store);
    check_samples(&path, &options(), false);
    reads_like(&path, &plain);

    let grid = truth_grid(None, |v| v);
    for (name, predictor) in [("be_f32.tif", 1), ("be_f32_pred3.tif", 3)] {
        let layout = big(50000, predictor, Chunking::Strips(4));
        let store = |s: &[f32], (w, _): (usize, usize)| {
            zstd(&if predictor == 3 {
                float_differences(s, w)
            } else {
                raw(s, true)
            })
        };
        let (path, plain) = write_pair(dir.path(), name, &grid, &layout, store);
        check_samples(&path, &options(), false);
        reads_like(&path, &plain);
    }
}

#[test]
fn geotiff_lerc_float32_tiled_with_a_mask_for_nodata() {
    let dir = tempfile::tempdir().unwrap();
    let layout = Layout {
        compression: 34887,
        tags: vec![(LERC_PARAMETERS, Value::Long(vec![4, 0]))],
        ..Layout::new(Chunking::Tiles(16, 16))
    };
    // LERC's masked samples read as NaN; the uncompressed twin stores NaN there.
    let grid = truth_grid(Some(f32::NAN), |v| v);
    let store = |s: &[f32], dims: (usize, usize)| {
        let zeroed: Vec<f32> = s
            .iter()
            .map(|x| if x.is_nan() { 0.0 } else { *x })
            .collect();
        lerc_blob(&zeroed, dims, |k| !s[k].is_nan())
    };
    let (path, plain) = write_pair(dir.path(), "lerc_f32.tif", &grid, &layout, store);
    check(&path, &options(), true);
    reads_like(&path, &plain);
    builds_like(&path, &plain);
}

#[test]
fn geotiff_lerc_inside_deflate_and_zstd() {
    let dir = tempfile::tempdir().unwrap();
    // LERC and DEFLATE over int16 strips, masked where the twin has GDAL's nodata.
    let layout = Layout {
        compression: 34887,
        tags: vec![(LERC_PARAMETERS, Value::Long(vec![4, 1])), nodata_tag()],
        ..Layout::new(Chunking::Strips(7))
    };
    let grid = truth_grid(Some(-9999i16), |v| v as i16);
    let store = |s: &[i16], dims: (usize, usize)| {
        let blob = lerc_blob(s, dims, |k| s[k] != -9999);
        miniz_oxide::deflate::compress_to_vec_zlib(&blob, 6)
    };
    let (path, plain) = write_pair(dir.path(), "lerc_deflate.tif", &grid, &layout, store);
    check(&path, &options(), true);
    reads_like(&path, &plain);

    // LERC and ZSTD over float32 tiles.
    let layout = Layout {
        compression: 34887,
        tags: vec![(LERC_PARAMETERS, Value::Long(vec![4, 2]))],
        ..Layout::new(Chunking::Tiles(32, 16))
    };
    let grid = truth_grid(None, |v: f32| v);
    let store = |s: &[f32], dims: (usize, usize)| zstd(&lerc_blob(s, dims, |_| true));
    let (path, plain) = write_pair(dir.path(), "lerc_zstd.tif", &grid, &layout, store);
    check_samples(&path, &options(), false);
    reads_like(&path, &plain);
}

#[test]
fn corrupt_zstd_and_lerc_chunks_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let err = |path: &Path| match dem::open(path, &options()).and_then(|r| r.read_all()) {
        Ok(_) => panic!("{} read", path.display()),
        Err(e) => e.to_string(),
    };
    let grid = truth_grid(None, |v: f32| v);
    let zstd_layout = Layout {
        compression: 50000,
        ..Layout::new(Chunking::Tiles(16, 16))
    };
    let lerc_layout = Layout {
        compression: 34887,
        ..Layout::new(Chunking::Tiles(16, 16))
    };
    // The fourth chunk cut short in one file, its bytes flipped in the other.
    let mut n = 0;
    let (zstd_path, _) = write_pair(dir.path(), "bad_zstd.tif", &grid, &zstd_layout, |s, _| {
        n += 1;
        let mut bytes = zstd(&raw(s, false));
        if n == 4 {
            bytes.truncate(bytes.len() / 2);
        }
        bytes
    });
    let e = err(&zstd_path);
    assert!(
        e.contains("bad_zstd.tif") && e.contains("corrupt TIFF chunk 3"),
        "{e}"
    );
    let mut n = 0;
    let (lerc_path, _) = write_pair(
        dir.path(),
        "bad_lerc.tif",
        &grid,
        &lerc_layout,
        |s, dims| {
            n += 1;
            let mut bytes = lerc_blob(s, dims, |_| true);
            if n == 4 {
                let half = bytes.len() / 2;
                bytes[half..].iter_mut().for_each(|b| *b ^= 0x5a);
            }
            bytes
        },
    );
    let e = err(&lerc_path);
    assert!(
        e.contains("bad_lerc.tif") && e.contains("corrupt TIFF chunk 3"),
        "{e}"
    );

    // A LERC blob of another size than its tile.
    let (small, _) = write_pair(dir.path(), "small_lerc.tif", &grid, &lerc_layout, |s, _| {
        lerc_blob(&s[..64], (8, 8), |_| true)
    });
    let e = err(&small);
    assert!(
        e.contains("small_lerc.tif")
            && e.contains("8 x 8 samples")
            && e.contains("16 x 16 expected"),
        "{e}"
    );
}

/// GDAL's fixture `name`, its chunks (DEFLATE over the predictor's differences) inflated and
/// compressed again with ZSTD, the predictor and nodata kept.
fn gdal_chunks_as_zstd<T: Sample>(name: &str, out: &Path) {
    use tiff::decoder::{ChunkType, Decoder};
    use tiff::tags::Tag;
    let file = std::fs::read(fixture(name)).unwrap();
    let mut decoder = Decoder::new(std::io::Cursor::new(&file)).unwrap();
    let (cw, ch) = decoder.chunk_dimensions();
    let (chunking, offsets, counts) = match decoder.get_chunk_type() {
        ChunkType::Tile => (
            Chunking::Tiles(cw, ch),
            Tag::TileOffsets,
            Tag::TileByteCounts,
        ),
        ChunkType::Strip => (
            Chunking::Strips(ch),
            Tag::StripOffsets,
            Tag::StripByteCounts,
        ),
    };
    let offsets = decoder.get_tag_u64_vec(offsets).unwrap();
    let counts = decoder.get_tag_u64_vec(counts).unwrap();
    let mut chunks = offsets.iter().zip(&counts).map(|(&at, &n)| {
        let stored = &file[at as usize..(at + n) as usize];
        zstd(&miniz_oxide::inflate::decompress_to_vec_zlib(stored).unwrap())
    });
    let layout = Layout {
        compression: 50000,
        predictor: decoder.get_tag_u32(Tag::Predictor).unwrap() as u16,
        tags: vec![(
            42113,
            Value::Ascii(decoder.get_tag_ascii_string(Tag::GdalNodata).unwrap()),
        )],
        ..Layout::new(chunking)
    };
    let grid = vec![T::default(); W * H];
    let bytes = tiff((W as u32, H as u32), &grid, &layout, |_, _| {
        chunks.next().unwrap()
    });
    std::fs::write(out, bytes).unwrap();
}

#[test]
fn gdal_predictor_chunks_recompressed_as_zstd_read_as_gdal_wrote_them() {
    let dir = tempfile::tempdir().unwrap();
    let int16 = dir.path().join("gdal_i16_zstd.tif");
    gdal_chunks_as_zstd::<i16>("int16_deflate_pred2_nodata.tif", &int16);
    check_samples(&int16, &options(), true);
    let float32 = dir.path().join("gdal_f32_zstd.tif");
    gdal_chunks_as_zstd::<f32>("float32_deflate_pred3_tiled_nodata.tif", &float32);
    check_samples(&float32, &options(), true);
}
