//! Many files as one DEM: tiles placed by their georeferencing (files, folders, globs) and GDAL
//! VRT mosaics, against the same grid read whole.

use std::path::{Path, PathBuf};

use proptest::prelude::*;
use stripmask::db::builder::{BuildOptions, build_inputs};
use stripmask::db::dem::{self, OpenOptions};

use crate::support::tiff_writer::{Tags, write_geotiff};

/// A height field with features in every direction and a little of everything in the fraction.
fn height(i: u32, j: u32) -> f32 {
    100.0 + 3.5 * i as f32 + 2.25 * j as f32 + ((i * 7 + j * 13) % 17) as f32 * 0.5
}

/// GeoKeys of WGS 84 / UTM zone 10N.
const UTM10: &[(u16, u16)] = &[(1024, 1), (3072, 32610)];

/// Writes a Float32 GeoTIFF of `w x h` samples `f(i, j)` whose first pixel's corner lies at
/// `corner` with cells of `cell` CRS units, with GeoKeys `keys` and GDAL nodata `nodata`.
fn write_tiff(
    path: &Path,
    size: (u32, u32),
    f: impl Fn(u32, u32) -> f32,
    corner: [f64; 2],
    cell: [f64; 2],
    keys: &[(u16, u16)],
    nodata: Option<&str>,
) {
    let tags = Tags {
        nodata,
        georeference: Some((cell, corner)),
        keys,
        ..Tags::default()
    };
    write_geotiff::<tiff::encoder::colortype::Gray32Float>(path, size, f, &tags);
}

/// Why opening `inputs` as one DEM fails.
fn refused(inputs: &[PathBuf]) -> String {
    dem::open_inputs(inputs, &OpenOptions::default())
        .err()
        .expect("refused")
        .to_string()
}

/// The whole grid of 70 x 50 samples (10 m cells, a nodata hole) and its four quarters, cut
/// at column 35 and row 25, in `dir`; returns the whole file and the quarters.
fn whole_and_quarters(dir: &Path) -> (PathBuf, Vec<PathBuf>) {
    let (w, h) = (70, 50);
    let corner = [500_000.0, 5_200_000.0];
    let value = |i: u32, j: u32| {
        if (30..40).contains(&i) && (20..24).contains(&j) {
            -9999.0
        } else {
            height(i, j)
        }
    };
    let whole = dir.join("whole.tif");
    write_tiff(
        &whole,
        (w, h),
        value,
        corner,
        [10.0, 10.0],
        UTM10,
        Some("-9999"),
    );
    std::fs::create_dir(dir.join("tiles")).unwrap();
    let mut quarters = Vec::new();
    for (qy, y0, qh) in [(0, 0, 25), (1, 25, 25)] {
        for (qx, x0, qw) in [(0, 0, 35), (1, 35, 35)] {
            let path = dir.join(format!("tiles/q{qy}{qx}.tif"));
            let corner = [
                corner[0] + f64::from(x0) * 10.0,
                corner[1] - f64::from(y0) * 10.0,
            ];
            let f = |i, j| value(i + x0, j + y0);
            write_tiff(
                &path,
                (qw, qh),
                f,
                corner,
                [10.0, 10.0],
                UTM10,
                Some("-9999"),
            );
            quarters.push(path);
        }
    }
    (whole, quarters)
}

/// Builds `inputs` into `out` with 17-sample tiles; the archive's bytes and the report's notes.
fn build_bytes(inputs: &[PathBuf], out: &Path) -> (Vec<u8>, Vec<String>) {
    let options = BuildOptions {
        tile_size: 17,
        ..BuildOptions::default()
    };
    let report = build_inputs(inputs, &OpenOptions::default(), out, &options, &|_, _| {})
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(report.crs.as_deref(), Some("EPSG:32610 (metres)"));
    (std::fs::read(out).unwrap(), report.notes)
}

#[test]
fn four_quarter_files_build_the_whole_file_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let (whole, mut quarters) = whole_and_quarters(dir.path());
    let (want, _) = build_bytes(std::slice::from_ref(&whole), &dir.path().join("whole.smdb"));
    // In any order, as a list, a folder, or a glob pattern the shell left alone.
    quarters.reverse();
    let (listed, notes) = build_bytes(&quarters, &dir.path().join("listed.smdb"));
    assert!(
        want == listed,
        "the mosaic's archive differs from the whole file's"
    );
    assert!(
        notes.iter().any(|n| n.contains("a mosaic of 4 files")),
        "{notes:?}"
    );
    let (folder, _) = build_bytes(&[dir.path().join("tiles")], &dir.path().join("folder.smdb"));
    assert!(want == folder);
    let pattern = dir.path().join("tiles/q*.tif");
    let (globbed, _) = build_bytes(&[pattern], &dir.path().join("glob.smdb"));
    assert!(want == globbed);
}

/// A VRT as `gdalbuildvrt` writes one over the four quarters, with `extra` inside each source.
fn quarters_vrt(kind: &str, extra: &str) -> String {
    let srs = r#"PROJCS["WGS 84 / UTM zone 10N",GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563,AUTHORITY["EPSG","7030"]],AUTHORITY["EPSG","6326"]],PRIMEM["Greenwich",0,AUTHORITY["EPSG","8901"]],UNIT["degree",0.0174532925199433,AUTHORITY["EPSG","9122"]],AUTHORITY["EPSG","4326"]],PROJECTION["Transverse_Mercator"],PARAMETER["latitude_of_origin",0],PARAMETER["central_meridian",-123],PARAMETER["scale_factor",0.9996],PARAMETER["false_easting",500000],PARAMETER["false_northing",0],UNIT["metre",1,AUTHORITY["EPSG","9001"]],AXIS["Easting",EAST],AXIS["Northing",NORTH],AUTHORITY["EPSG","32610"]]"#;
    let mut sources = String::new();
    for (qy, y0) in [(0, 0), (1, 25)] {
        for (qx, x0) in [(0, 0), (1, 35)] {
            sources += &format!(
                r#"    <{kind}>
      <SourceFilename relativeToVRT="1">tiles/q{qy}{qx}.tif</SourceFilename>
      <SourceBand>1</SourceBand>
      <SourceProperties RasterXSize="35" RasterYSize="25" DataType="Float32" BlockXSize="35" BlockYSize="1" />
      <SrcRect xOff="0" yOff="0" xSize="35" ySize="25" />
      <DstRect xOff="{x0}" yOff="{y0}" xSize="35" ySize="25" />
{extra}    </{kind}>
"#
            );
        }
    }
    format!(
        r#"<VRTDataset rasterXSize="70" rasterYSize="50">
  <SRS dataAxisToSRSAxisMapping="1,2">{srs}</SRS>
  <GeoTransform>  5.0000000000000000e+05,  1.0000000000000000e+01,  0.0000000000000000e+00,  5.2000000000000000e+06,  0.0000000000000000e+00, -1.0000000000000000e+01</GeoTransform>
  <VRTRasterBand dataType="Float32" band="1">
    <NoDataValue>-9999</NoDataValue>
    <ColorInterp>Gray</ColorInterp>
{sources}  </VRTRasterBand>
</VRTDataset>
"#
    )
}

#[test]
fn a_gdal_vrt_of_the_quarters_builds_the_whole_file_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let (whole, _) = whole_and_quarters(dir.path());
    let (want, _) = build_bytes(&[whole], &dir.path().join("whole.smdb"));
    for (kind, extra) in [
        ("SimpleSource", ""),
        ("ComplexSource", "      <NODATA>-9999</NODATA>\n"),
    ] {
        let vrt = dir.path().join("mosaic.vrt");
        std::fs::write(&vrt, quarters_vrt(kind, extra)).unwrap();
        let (got, notes) = build_bytes(&[vrt], &dir.path().join("vrt.smdb"));
        assert!(want == got, "{kind}: the VRT's archive differs");
        assert!(
            notes.iter().any(|n| n.contains("GDAL VRT of 4 sources")),
            "{notes:?}"
        );
    }
}

#[test]
fn a_complex_source_scales_its_raw_values_and_the_last_source_with_data_wins() {
    let dir = tempfile::tempdir().unwrap();
    whole_and_quarters(dir.path());
    // Every source in decimetres: ScaleRatio 0.1, then the band's own scale of 10 undoes it.
    let vrt = quarters_vrt("ComplexSource", "      <ScaleRatio>0.1</ScaleRatio>\n")
        .replace("<ColorInterp>", "<Scale>10</Scale><ColorInterp>");
    let path = dir.path().join("scaled.vrt");
    std::fs::write(&path, vrt).unwrap();
    let dem = dem::open(&path, &OpenOptions::default())
        .unwrap()
        .read_all()
        .unwrap();
    assert!((dem.at(3, 4) - height(3, 4)).abs() < 1e-3);
    assert!((dem.at(69, 49) - height(69, 49)).abs() < 1e-3);
    // A fifth source over the first quarter with nodata everywhere but its own samples:
    // listed last, it wins where it has data and leaves the rest to the quarters.
    let patch = dir.path().join("patch.tif");
    let f = |i: u32, j: u32| if i == 1 && j == 1 { 7.0 } else { -9999.0 };
    let corner = [500_000.0, 5_200_000.0];
    write_tiff(
        &patch,
        (4, 4),
        f,
        corner,
        [10.0, 10.0],
        UTM10,
        Some("-9999"),
    );
    let tiles: Vec<PathBuf> = std::fs::read_dir(dir.path().join("tiles"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    let mut listed = tiles.clone();
    listed.sort();
    listed.push(patch.clone());
    let dem = dem::open_inputs(&listed, &OpenOptions::default())
        .unwrap()
        .read_all()
        .unwrap();
    assert_eq!(dem.at(1, 1), 7.0);
    assert_eq!(dem.at(2, 1), height(2, 1));
    // Listed first, the patch loses to the quarter under it.
    listed.rotate_right(1);
    let dem = dem::open_inputs(&listed, &OpenOptions::default())
        .unwrap()
        .read_all()
        .unwrap();
    assert_eq!(dem.at(1, 1), height(1, 1));
}

/// Writes an SRTM-style `.hgt` of `side x side` big-endian samples `f(i, j)`.
fn write_hgt(path: &Path, side: u32, f: impl Fn(u32, u32) -> i16) {
    let bytes: Vec<u8> = (0..side * side)
        .flat_map(|k| f(k % side, k / side).to_be_bytes())
        .collect();
    std::fs::write(path, bytes).unwrap();
}

#[test]
fn srtm_tiles_are_placed_by_their_names_sharing_their_edge() {
    // Two 1° tiles of 121 x 121 samples (30" cells) side by side: the column they share is
    // the western one's last and the eastern one's first.
    let dir = tempfile::tempdir().unwrap();
    let side = 121;
    let global = |i: u32, j: u32| (500 + 2 * i + j) as i16;
    write_hgt(&dir.path().join("N46W122.hgt"), side, global);
    write_hgt(&dir.path().join("N46W121.hgt"), side, |i, j| {
        global(i + 120, j)
    });
    // Written whole, too, as a GeoTIFF would be after gdal_merge.
    let reader = dem::open_inputs(&[dir.path().to_path_buf()], &OpenOptions::default()).unwrap();
    let info = reader.info().clone();
    assert_eq!((info.width, info.height), (241, 121));
    let p = info.placement.clone().unwrap();
    assert_eq!(p.crs, "EPSG:4326");
    assert!((p.first.0 + 122.0).abs() < 1e-9 && (p.first.1 - 47.0).abs() < 1e-9);
    let dem = reader.read_all().unwrap();
    for (i, j) in [(0, 0), (119, 5), (120, 60), (121, 7), (240, 120)] {
        assert_eq!(
            dem.at(i, j),
            f32::from(global(i as u32, j as u32)),
            "({i}, {j})"
        );
    }
}

#[test]
fn tiles_of_other_cells_are_resampled_to_the_finest_and_gaps_are_nodata() {
    let dir = tempfile::tempdir().unwrap();
    // A plane, so bilinear resampling is exact: 10 m cells west, 20 m cells east of it.
    let plane = |x: f64, y: f64| (1000.0 + 0.25 * x - 0.5 * y) as f32;
    let (x0, y0) = (500_000.0, 5_200_000.0);
    let fine = dir.path().join("fine.tif");
    write_tiff(
        &fine,
        (21, 21),
        |i, j| plane(5.0 + 10.0 * f64::from(i), -5.0 - 10.0 * f64::from(j)),
        [x0, y0],
        [10.0, 10.0],
        UTM10,
        None,
    );
    // The coarse tile starts 200 m east, its first sample centre 10 m in.
    let coarse = dir.path().join("coarse.tif");
    let c = |i: u32, j: u32| plane(210.0 + 20.0 * f64::from(i), -10.0 - 20.0 * f64::from(j));
    write_tiff(
        &coarse,
        (6, 6),
        c,
        [x0 + 200.0, y0],
        [20.0, 20.0],
        UTM10,
        None,
    );
    // A third tile far to the south-east leaves a gap of nodata.
    let far = dir.path().join("far.tif");
    write_tiff(
        &far,
        (4, 4),
        |_, _| 50.0,
        [x0 + 600.0, y0 - 600.0],
        [10.0, 10.0],
        UTM10,
        None,
    );
    let reader = dem::open_inputs(&[fine, coarse, far], &OpenOptions::default()).unwrap();
    let notes = reader.info().notes.join("\n");
    assert!(
        notes.contains("coarse.tif: cells of 20 x 20 metres resampled"),
        "{notes}"
    );
    let (w, h) = (reader.info().width, reader.info().height);
    assert_eq!((w, h), (64, 64));
    let mut rows = vec![vec![false; w]; h];
    let dem = {
        let mut reader = reader;
        let mut samples = vec![0.0; w * h];
        for (j, row) in samples.chunks_exact_mut(w).enumerate() {
            reader.read_row_marking(row, Some(&mut rows[j])).unwrap();
        }
        samples
    };
    // Inside the coarse tile, between its samples: the plane.
    for (i, j) in [(22, 1), (23, 2), (30, 9)] {
        let want = plane(5.0 + 10.0 * i as f64, -5.0 - 10.0 * j as f64);
        assert!((dem[j * w + i] - want).abs() < 1e-3, "({i}, {j})");
        assert!(!rows[j][i]);
    }
    // Between the tiles, nothing: nodata (then filled for the build).
    assert!(rows[40][10] && rows[30][50]);
    assert!(!rows[62][62]);
}

#[test]
fn mismatched_or_unplaced_files_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let utm = dir.path().join("utm10.tif");
    write_tiff(
        &utm,
        (8, 8),
        height,
        [500_000.0, 5_200_000.0],
        [10.0, 10.0],
        UTM10,
        None,
    );
    let utm11 = dir.path().join("utm11.tif");
    let keys = [(1024, 1), (3072, 32611)];
    write_tiff(
        &utm11,
        (8, 8),
        height,
        [500_000.0, 5_200_000.0],
        [10.0, 10.0],
        &keys,
        None,
    );
    let e = refused(&[utm.clone(), utm11]);
    assert!(
        e.contains("utm11.tif")
            && e.contains("EPSG:32611")
            && e.contains("EPSG:32610")
            && e.contains("utm10.tif"),
        "{e}"
    );
    let png = dir.path().join("plain.png");
    image::GrayImage::from_pixel(8, 8, image::Luma([9]))
        .save(&png)
        .unwrap();
    let e = refused(&[utm.clone(), png]);
    assert!(
        e.contains("plain.png") && e.contains("cannot be placed in a mosaic"),
        "{e}"
    );
    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let e = refused(&[empty]);
    assert!(e.contains("empty") && e.contains("no DEM file"), "{e}");
    let e = refused(&[dir.path().join("none*.tif")]);
    assert!(e.contains("matches no file"), "{e}");
    // A VRT listing itself is stopped, not followed for ever.
    let selfish = dir.path().join("self.vrt");
    let xml = r#"<VRTDataset rasterXSize="8" rasterYSize="8"><VRTRasterBand band="1"><SimpleSource><SourceFilename relativeToVRT="1">self.vrt</SourceFilename></SimpleSource></VRTRasterBand></VRTDataset>"#;
    std::fs::write(&selfish, xml).unwrap();
    let e = dem::open(&selfish, &OpenOptions::default())
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("self.vrt") && e.contains("VRTs deep"), "{e}");
}

#[test]
fn files_are_opened_when_the_rows_reach_them() {
    // Four tiles stacked north to south: the southern one is broken after the mosaic is
    // planned; reading the rows of the others still works, and its own rows fail by name.
    let dir = tempfile::tempdir().unwrap();
    let mut paths = Vec::new();
    for k in 0..4u32 {
        let path = dir.path().join(format!("strip{k}.tif"));
        let corner = [500_000.0, 5_200_000.0 - f64::from(k) * 100.0];
        write_tiff(
            &path,
            (10, 10),
            |i, j| height(i, j + 10 * k),
            corner,
            [10.0, 10.0],
            UTM10,
            None,
        );
        paths.push(path);
    }
    let mut reader = dem::Mosaic::placed(&paths, &OpenOptions::default(), 0).unwrap();
    use stripmask::db::dem::DemReader;
    std::fs::write(&paths[3], b"not a TIFF any more").unwrap();
    let mut row = vec![0.0; 10];
    for j in 0..30 {
        reader.read_row(&mut row).unwrap();
        assert_eq!(row[4], height(4, j));
    }
    let e = reader.read_row(&mut row).err().unwrap().to_string();
    assert!(e.contains("strip3.tif"), "{e}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// A VRT with bytes changed, cut short or its numbers and SRS replaced is read or refused
    /// by name, never a panic.
    #[test]
    fn a_mangled_vrt_is_an_error_or_a_grid(
        cut in 0usize..4000,
        flips in proptest::collection::vec((0usize..4000, any::<u8>()), 0..6),
        number in prop_oneof![Just("-1".to_string()), Just("1e308".to_string()), Just("nan".to_string()), Just("0".to_string()), "[0-9]{1,12}"],
        srs in "[A-Z_\\[\\]\",0-9. ]{0,60}",
    ) {
        let dir = tempfile::tempdir().unwrap();
        whole_and_quarters(dir.path());
        let mut xml = quarters_vrt("ComplexSource", "").into_bytes();
        for (at, byte) in flips {
            let at = at % xml.len();
            xml[at] = byte;
        }
        xml.truncate(cut.max(1).min(xml.len()) + if cut % 2 == 0 { xml.len() } else { 0 });
        let xml = String::from_utf8_lossy(&xml)
            .replace("\"35\"", &format!("\"{number}\""))
            .replace("PROJCS[\"WGS 84 / UTM zone 10N\"", &srs);
        let path = dir.path().join("m.vrt");
        std::fs::write(&path, xml).unwrap();
        match dem::open(&path, &OpenOptions::default()) {
            Ok(reader) => {
                let (w, h) = (reader.info().width, reader.info().height);
                if w * h <= 1 << 16
                    && let Err(e) = reader.read_all() {
                        prop_assert!(!e.to_string().is_empty());
                    }
            }
            Err(e) => prop_assert!(e.to_string().contains("m.vrt") || e.to_string().contains("tiles"), "{}", e),
        }
    }
}

/// Writes a 4 x 3 ASCII grid of 10 m cells whose south-west corner lies at `(x, y)`, with a
/// `.prj` of `wkt` beside it when given.
fn write_asc(path: &Path, (x, y): (f64, f64), wkt: Option<&str>) {
    let mut text = format!("ncols 4\nnrows 3\nxllcorner {x}\nyllcorner {y}\ncellsize 10\n");
    for j in 0..3 {
        let row: Vec<String> = (0..4).map(|i| height(i, j).to_string()).collect();
        text += &(row.join(" ") + "\n");
    }
    std::fs::write(path, text).unwrap();
    if let Some(wkt) = wkt {
        std::fs::write(path.with_extension("prj"), wkt).unwrap();
    }
}

#[test]
fn ascii_grids_take_their_crs_from_the_prj_beside_them() {
    let dir = tempfile::tempdir().unwrap();
    let utm = |zone: u32| {
        format!(
            r#"PROJCS["WGS 84 / UTM zone {zone}N",UNIT["metre",1],AUTHORITY["EPSG","326{zone}"]]"#
        )
    };
    let (a, b, c) = (
        dir.path().join("a.asc"),
        dir.path().join("b.asc"),
        dir.path().join("c.asc"),
    );
    write_asc(&a, (500_000.0, 5_199_970.0), Some(&utm(10)));
    write_asc(&b, (500_040.0, 5_199_970.0), Some(&utm(10)));
    write_asc(&c, (500_080.0, 5_199_970.0), Some(&utm(11)));
    let reader = dem::open_inputs(&[a.clone(), b], &OpenOptions::default()).unwrap();
    assert_eq!(reader.info().placement.as_ref().unwrap().crs, "EPSG:32610");
    assert_eq!(reader.info().width, 8);
    let dem = reader.read_all().unwrap();
    assert_eq!(dem.at(5, 2), height(1, 2));
    let e = refused(&[a, c]);
    assert!(e.contains("EPSG:32611") && e.contains("c.asc"), "{e}");
}

#[test]
fn the_command_builds_a_folder_and_info_says_how_a_dem_reads() {
    use crate::support::cli::stripmask;
    let dir = tempfile::tempdir().unwrap();
    whole_and_quarters(dir.path());
    let tiles = dir.path().join("tiles");
    // The standard output of a run that must succeed.
    let stdout = |command: &mut std::process::Command| {
        let out = command.output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{err}");
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let text = stdout(stripmask().arg("info").arg(&tiles));
    assert!(
        text.contains("(4 files)") && text.contains("crs         EPSG:32610 (metres)"),
        "{text}"
    );
    assert!(text.contains("grid        70 x 50 samples"), "{text}");
    let json = stdout(
        stripmask()
            .args(["info", "--json", "--check"])
            .arg(dir.path().join("tiles/q0*.tif")),
    );
    let json: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(json["files"], 2);
    assert_eq!(json["width"], 70);
    assert!(json["check"]["nodata_filled"].as_u64().unwrap() > 0);
    let archive = dir.path().join("m.smdb");
    let text = stdout(
        stripmask()
            .args(["build", "--tile-size", "17", "-o"])
            .arg(&archive)
            .arg(dir.path().join("tiles/q00.tif"))
            .arg(dir.path().join("tiles/q01.tif"))
            .arg(dir.path().join("tiles/q1*.tif")),
    );
    assert!(
        text.contains("crs         EPSG:32610 (metres)") && text.contains("a mosaic of 4 files"),
        "{text}"
    );
    // The output is never one of the inputs, however it is named.
    let out = stripmask()
        .args(["build", "-o"])
        .arg(dir.path().join("tiles/q11.tif"))
        .arg(&tiles)
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("q11.tif"));
}

#[test]
fn pixel_is_point_and_pixel_is_area_tiles_meet_on_one_grid() {
    // The western tile's tie point is its first pixel's corner (PixelIsArea, the default);
    // the eastern one's is its first sample's centre (PixelIsPoint): half a cell apart, and
    // read right, they meet without resampling.
    let dir = tempfile::tempdir().unwrap();
    let area = dir.path().join("area.tif");
    write_tiff(
        &area,
        (8, 6),
        height,
        [500_000.0, 5_200_000.0],
        [10.0, 10.0],
        UTM10,
        None,
    );
    let point = dir.path().join("point.tif");
    let keys = [(1024, 1), (1025, 2), (3072, 32610)];
    let east = |i, j| height(i + 8, j);
    write_tiff(
        &point,
        (8, 6),
        east,
        [500_085.0, 5_199_995.0],
        [10.0, 10.0],
        &keys,
        None,
    );
    let reader = dem::open_inputs(&[area, point], &OpenOptions::default()).unwrap();
    assert!(
        !reader.info().notes.join(" ").contains("resampled"),
        "{:?}",
        reader.info().notes
    );
    assert_eq!(reader.info().width, 16);
    let dem = reader.read_all().unwrap();
    for (i, j) in [(7, 0), (8, 0), (15, 5)] {
        assert_eq!(dem.at(i, j), height(i as u32, j as u32));
    }
}

#[test]
fn a_cloud_optimized_geotiff_reads_its_full_resolution_image_not_its_overviews_or_mask() {
    use tiff::encoder::{
        TiffEncoder,
        colortype::{Gray8, Gray32Float},
    };
    use tiff::tags::Tag;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cog.tif");
    let mut encoder = TiffEncoder::new(std::fs::File::create(&path).unwrap()).unwrap();
    let full: Vec<f32> = (0..16 * 12).map(|k| height(k % 16, k / 16)).collect();
    let mut image = encoder.new_image::<Gray32Float>(16, 12).unwrap();
    image
        .encoder()
        .write_tag(Tag::ModelPixelScaleTag, &[10.0, 10.0, 0.0][..])
        .unwrap();
    image.write_data(&full).unwrap();
    // An overview (NewSubfileType 1) and a mask (4), as GDAL writes after the image.
    let mut overview = encoder.new_image::<Gray32Float>(8, 6).unwrap();
    overview
        .encoder()
        .write_tag(Tag::NewSubfileType, 1u32)
        .unwrap();
    overview.write_data(&[0.0f32; 48]).unwrap();
    let mut mask = encoder.new_image::<Gray8>(16, 12).unwrap();
    mask.encoder().write_tag(Tag::NewSubfileType, 4u32).unwrap();
    mask.write_data(&[0u8; 192]).unwrap();
    let dem = dem::open(&path, &OpenOptions::default())
        .unwrap()
        .read_all()
        .unwrap();
    assert_eq!((dem.width, dem.height), (16, 12));
    assert_eq!(dem.at(15, 11), height(15, 11));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Any grid cut into pieces at any columns and rows, overlapping their neighbours by any
    /// few samples and listed in any order, reads back as the grid, sample for sample.
    #[test]
    fn any_cut_of_a_grid_reads_back_as_the_grid(
        (w, h) in (3u32..40, 3u32..40),
        cuts_x in proptest::collection::vec(1u32..39, 0..3),
        cuts_y in proptest::collection::vec(1u32..39, 0..3),
        overlap in 0u32..3,
        order in any::<u64>(),
    ) {
        use stripmask::db::dem::DemReader;
        let dir = tempfile::tempdir().unwrap();
        let spans = |n: u32, cuts: &[u32]| {
            let mut at: Vec<u32> = cuts.iter().map(|c| c % (n - 1) + 1).collect();
            at.extend([0, n]);
            at.sort();
            at.dedup();
            at.windows(2)
                .map(|p| (p[0].saturating_sub(overlap), (p[1] + overlap).min(n)))
                .filter(|(a, b)| b - a >= 2)
                .collect::<Vec<_>>()
        };
        let mut paths = Vec::new();
        for (y0, y1) in spans(h, &cuts_y) {
            for (x0, x1) in spans(w, &cuts_x) {
                let path = dir.path().join(format!("p{x0}_{y0}.tif"));
                let corner = [500_000.0 + f64::from(x0) * 10.0, 5_200_000.0 - f64::from(y0) * 10.0];
                let f = |i, j| height(i + x0, j + y0);
                write_tiff(&path, (x1 - x0, y1 - y0), f, corner, [10.0, 10.0], UTM10, None);
                paths.push(path);
            }
        }
        prop_assume!(!paths.is_empty());
        // A seeded shuffle of the listing order.
        let mut seed = order;
        for k in (1..paths.len()).rev() {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            paths.swap(k, (seed >> 33) as usize % (k + 1));
        }
        let mut reader = dem::Mosaic::placed(&paths, &OpenOptions::default(), 0).unwrap();
        let (mw, mh) = (reader.info().width, reader.info().height);
        // Where the mosaic starts in the grid: pieces narrower than 2 samples are not written,
        // so it may start past the grid's first row or column, and their samples are nodata.
        let first = reader.info().placement.as_ref().unwrap().first;
        let i0 = ((first.0 - 500_005.0) / 10.0).round() as u32;
        let j0 = ((5_199_995.0 - first.1) / 10.0).round() as u32;
        let mut row = vec![0.0; mw];
        for j in 0..mh {
            reader.read_row(&mut row).unwrap();
            for (i, v) in row.iter().enumerate() {
                let want = height(i as u32 + i0, j as u32 + j0);
                prop_assert!(v.is_nan() || *v == want, "({}, {}) {} not {}", i, j, v, want);
            }
        }
    }
}
