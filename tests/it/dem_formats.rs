//! Every DEM reader against fixtures written by GDAL, and a build/read round trip per format.

use std::path::{Path, PathBuf};
use stripmask::db::grid::TileId;

use stripmask::db::archive::ArchiveReader;
use stripmask::db::builder::{BuildOptions, build};
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

/// The tags a test GeoTIFF carries besides its samples.
#[derive(Default)]
struct Tags<'a> {
    /// GDAL's metadata XML.
    metadata: Option<&'a str>,
    /// GDAL's nodata text.
    nodata: Option<&'a str>,
    /// Pixel scale (x, y) and the world position of the first pixel's corner.
    georeference: Option<([f64; 2], [f64; 2])>,
    /// GeoKeys `(id, value)`, short values.
    keys: &'a [(u16, u16)],
}

/// Writes a UInt16 TIFF of `w x h` samples `raw(i, j)` with `tags`.
fn write_u16_tiff(path: &Path, (w, h): (u32, u32), raw: impl Fn(u32, u32) -> u16, tags: &Tags) {
    use tiff::encoder::{TiffEncoder, colortype::Gray16};
    use tiff::tags::Tag;
    let data: Vec<u16> = (0..w * h).map(|k| raw(k % w, k / w)).collect();
    let mut encoder = TiffEncoder::new(std::fs::File::create(path).unwrap()).unwrap();
    let mut image = encoder.new_image::<Gray16>(w, h).unwrap();
    let dir = image.encoder();
    if let Some(metadata) = tags.metadata {
        dir.write_tag(Tag::Unknown(42112), metadata).unwrap();
    }
    if let Some(nodata) = tags.nodata {
        dir.write_tag(Tag::GdalNodata, nodata).unwrap();
    }
    if let Some((scale, corner)) = tags.georeference {
        dir.write_tag(Tag::ModelPixelScaleTag, &[scale[0], scale[1], 0.0][..])
            .unwrap();
        dir.write_tag(
            Tag::ModelTiepointTag,
            &[0.0, 0.0, 0.0, corner[0], corner[1], 0.0][..],
        )
        .unwrap();
    }
    if !tags.keys.is_empty() {
        let mut directory = vec![1, 1, 0, tags.keys.len() as u16];
        for &(id, value) in tags.keys {
            directory.extend([id, 0, 1, value]);
        }
        dir.write_tag(Tag::GeoKeyDirectoryTag, &directory[..])
            .unwrap();
    }
    image.write_data(&data).unwrap();
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
