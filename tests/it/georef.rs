//! Georeferenced archives: a GeoTIFF in UTM and one in degrees keep their CRS and placement in
//! the archive, latitudes and longitudes land where independent arithmetic puts them, and pose
//! feeds in latitude and longitude (`geo` lines, NMEA 0183) steer the camera there. Damaged
//! georeferencing and any feed line give errors, never panics.

use std::path::{Path, PathBuf};

use proptest::prelude::*;
use stripmask::db::archive::{ArchiveReader, HEADER_LEN, Header};
use stripmask::db::builder::{BuildOptions, BuildReport, build, build_file};
use stripmask::db::dem::{MemoryReader, NodataFill, OpenOptions, Units};
use stripmask::db::georef::Georef;
use stripmask::db::source::{self, file::FileSource};
use stripmask::engine::{Engine, EngineSettings};
use stripmask::sim::pose::line::PoseDecoder;
use stripmask::sim::pose::nmea::with_checksum;
use stripmask::sim::pose::{PoseFeed, PoseSource};

use crate::support::cli::{plain_archive, stripmask};
use crate::support::tiff_writer::{Tags, write_geotiff};

/// WGS 84's ellipsoid.
const A: f64 = 6_378_137.0;
const F: f64 = 1.0 / 298.257_223_563;
/// UTM's central scale factor.
const K0: f64 = 0.9996;

/// A meridian's arc from the equator to `phi` on WGS 84 (Helmert's series), metres.
fn meridian_arc(phi: f64) -> f64 {
    let n = F / (2.0 - F);
    let (n2, n3, n4) = (n * n, n * n * n, n * n * n * n);
    A / (1.0 + n)
        * ((1.0 + n2 / 4.0 + n4 / 64.0) * phi - 1.5 * (n - n3 / 8.0) * (2.0 * phi).sin()
            + 15.0 / 16.0 * (n2 - n4 / 4.0) * (4.0 * phi).sin()
            - 35.0 / 48.0 * n3 * (6.0 * phi).sin()
            + 315.0 / 512.0 * n4 * (8.0 * phi).sin())
}

/// UTM easting and northing (north zone) of `lat`, `lon` degrees around the central meridian
/// `meridian` by Redfearn's series (Snyder's form): independent of the engine's Krüger series.
fn redfearn(lat: f64, lon: f64, meridian: f64) -> (f64, f64) {
    let e2 = F * (2.0 - F);
    let ep2 = e2 / (1.0 - e2);
    let phi = lat.to_radians();
    let nu = A / (1.0 - e2 * phi.sin().powi(2)).sqrt();
    let t = phi.tan().powi(2);
    let c = ep2 * phi.cos().powi(2);
    let aa = (lon - meridian).to_radians() * phi.cos();
    let x = K0
        * nu
        * (aa
            + (1.0 - t + c) * aa.powi(3) / 6.0
            + (5.0 - 18.0 * t + t * t + 72.0 * c - 58.0 * ep2) * aa.powi(5) / 120.0);
    let y = K0
        * (meridian_arc(phi)
            + nu * phi.tan()
                * (aa * aa / 2.0
                    + (5.0 - t + 9.0 * c + 4.0 * c * c) * aa.powi(4) / 24.0
                    + (61.0 - 58.0 * t + t * t + 600.0 * c - 330.0 * ep2) * aa.powi(6) / 720.0));
    (500_000.0 + x, y)
}

/// Heights of the test models: a gentle slope, well below the cameras.
fn height(i: u32, j: u32) -> f32 {
    100.0 + 1.5 * i as f32 + 0.75 * j as f32
}

/// Writes a Float32 GeoTIFF of `size` samples whose first pixel's corner lies at `corner`,
/// cells `cell`, GeoKeys `keys`, and builds it into an archive of 33-sample tiles.
fn build_geotiff(
    dir: &Path,
    name: &str,
    size: (u32, u32),
    corner: [f64; 2],
    cell: [f64; 2],
    keys: &[(u16, u16)],
) -> (PathBuf, BuildReport) {
    let tif = dir.join(format!("{name}.tif"));
    let tags = Tags {
        georeference: Some((cell, corner)),
        keys,
        ..Tags::default()
    };
    write_geotiff::<tiff::encoder::colortype::Gray32Float>(&tif, size, height, &tags);
    let out = dir.join(format!("{name}.smdb"));
    let options = BuildOptions {
        tile_size: 33,
        ..BuildOptions::default()
    };
    let report = build_file(&tif, &OpenOptions::default(), &out, &options, &|_, _| {}).unwrap();
    (out, report)
}

fn open(path: &Path) -> ArchiveReader<FileSource> {
    ArchiveReader::open(FileSource::open(path).unwrap()).unwrap()
}

/// The feed of the recording `lines` over the archive `path`.
fn feed(dir: &Path, path: &Path, lines: &[String]) -> PoseFeed {
    let recording = dir.join("poses.txt");
    std::fs::write(&recording, lines.join("\n")).unwrap();
    let header = open(path).header().clone();
    let decoder = PoseDecoder::new(&path.display().to_string(), header);
    PoseFeed::open(&PoseSource::File(recording), decoder).unwrap()
}

/// The first sample's centre of the UTM model: column 30 on the central meridian of zone 10
/// (123 W), row 20 a little north of 47 N.
fn utm_first() -> (f64, f64) {
    let north_47 = K0 * meridian_arc(47f64.to_radians());
    (500_000.0 - 300.0, north_47.round() + 200.0)
}

/// The UTM model: 70 x 50 samples of 10 m, WGS 84 / UTM zone 10N.
fn utm_archive(dir: &Path) -> (PathBuf, BuildReport) {
    let (x, y) = utm_first();
    let corner = [x - 5.0, y + 5.0];
    let keys = [(1024, 1), (3072, 32610)];
    build_geotiff(dir, "utm", (70, 50), corner, [10.0, 10.0], &keys)
}

#[test]
fn a_utm_geotiff_keeps_its_crs_and_places_latitudes_where_redfearn_does() {
    let dir = tempfile::tempdir().unwrap();
    let (path, report) = utm_archive(dir.path());
    let reader = open(&path);
    let h = reader.header();
    let first = utm_first();
    let expected = Georef {
        crs: "EPSG:32610".into(),
        units: Units::Linear(1.0),
        first,
        cell: (10.0, 10.0),
    };
    assert_eq!(h.georef.as_ref(), Some(&expected));
    assert_eq!(h, &report.header);
    assert_eq!(h.header_len(), HEADER_LEN + 52 + "EPSG:32610".len());
    assert_eq!(
        reader.opening_bytes(),
        (h.header_len() + h.directory_len()) as u64
    );
    assert_eq!((h.origin_x, h.origin_y), first);
    let (x, y) = first;
    assert_eq!(
        h.corners(),
        Some([
            (x, y),
            (x + 690.0, y),
            (x, y - 490.0),
            (x + 690.0, y - 490.0)
        ])
    );
    // On the central meridian: column 30, and the northing the meridian's arc gives.
    let on = h.locate(47.0, -123.0, "utm").unwrap();
    assert!((on.east - 500_000.0).abs() < 1e-6, "{}", on.east);
    assert!((on.north - K0 * meridian_arc(47f64.to_radians())).abs() < 1e-3);
    assert_eq!(on.convergence, 0.0);
    for (lat, lon) in [(47.001, -122.996), (46.999, -123.0035), (47.0, -122.9962)] {
        let at = h.locate(lat, lon, "utm").unwrap();
        let (e, n) = redfearn(lat, lon, -123.0);
        assert!((at.east - e).abs() < 1e-3, "{lat} {lon}: {} {e}", at.east);
        assert!((at.north - n).abs() < 1e-3, "{lat} {lon}: {} {n}", at.north);
    }
}

#[test]
fn poses_in_latitude_and_longitude_and_nmea_land_the_camera_on_the_utm_archive() {
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = utm_archive(dir.path());
    let (first_x, first_y) = utm_first();
    let lines = [
        "# a drone over the ridge".to_string(),
        "geo 0 47 -123 2000 90 -10 0".to_string(),
        // 47 0.06' N, 122 59.76' W: 47.001 N, 122.996 W.
        with_checksum("GPRMC,120001,A,4700.060,N,12259.760,W,5.0,180.0,010125,,,A"),
        with_checksum("GPGGA,120001,4700.060,N,12259.760,W,1,09,0.8,2100.0,M,-22.0,M,,"),
        with_checksum("GPGGA,120002,,,,,0,00,,,,,,,"),
    ];
    // The recording's times run from its first line: 0, then NMEA's seconds of the day.
    let lines: Vec<String> = lines
        .iter()
        .map(|l| l.replace("geo 0 ", "geo 43200 "))
        .collect();
    let feed = feed(dir.path(), &path, &lines);
    let settings = EngineSettings::default();
    let engine = Engine::new(
        source::open(path.to_str().unwrap()).unwrap(),
        settings,
        stripmask::Viewport::new(320, 240),
    )
    .unwrap();
    let (pose, _) = feed.at(0.5).unwrap();
    let camera = pose.camera(&engine);
    // Column 30 (the central meridian), at the meridian arc's row.
    let row = (first_y - K0 * meridian_arc(47f64.to_radians())) / 10.0;
    assert!(
        (camera.position.x - 300.0).abs() < 1e-6,
        "{}",
        camera.position
    );
    assert!(
        (camera.position.z - row * 10.0).abs() < 1e-3,
        "{}",
        camera.position
    );
    assert_eq!(camera.position.y, 2000.0);
    assert!((pose.heading - 90f64.to_radians()).abs() < 1e-12);
    // An application places the same camera itself.
    let placed = engine
        .camera_at(
            (47.0, -123.0, 2000.0),
            90f64.to_radians(),
            -10f64.to_radians(),
            0.0,
        )
        .unwrap();
    assert!(
        (placed.position - camera.position).length() < 1e-9,
        "{placed:?}"
    );
    assert!(
        (placed.forward - camera.forward).length() < 1e-12,
        "{placed:?}"
    );
    let (e, n) = redfearn(47.001, -122.996, -123.0);
    let (there, convergence) = engine.locate(47.001, -122.996, 100.0).unwrap();
    assert!((there.x - (e - first_x)).abs() < 1e-3 && (there.z - (first_y - n)).abs() < 1e-3);
    assert!(convergence > 0.0 && convergence < 1e-3, "{convergence}");
    // The NMEA fix, a second later: where Redfearn puts 47.001 N, 122.996 W, heading the RMC
    // course less the grid convergence there (about 0.003 degrees).
    let (gps, _) = feed.at(1.5).unwrap();
    let (e, n) = redfearn(47.001, -122.996, -123.0);
    let camera = gps.camera(&engine);
    assert!(
        (camera.position.x - (e - first_x)).abs() < 1e-3,
        "{}",
        camera.position
    );
    assert!(
        (camera.position.z - (first_y - n)).abs() < 1e-3,
        "{}",
        camera.position
    );
    assert_eq!((camera.position.y, gps.pitch), (2100.0, 0.0));
    let convergence = (0.004f64).to_radians() * 47.001f64.to_radians().sin();
    assert!((gps.heading - (180f64.to_radians() - convergence)).abs() < 1e-7);
    // The void fix after it: the camera stays, the feed shows stale.
    assert_eq!(feed.at(2.5).unwrap().0, gps);
    assert!(feed.status(2.5).starts_with("POSE STALE") && feed.status(2.5).contains("NO FIX"));
}

#[test]
fn a_geographic_geotiff_keeps_its_degrees_and_places_latitudes_on_its_metres() {
    let dir = tempfile::tempdir().unwrap();
    let cell = 1.0 / 1200.0;
    let (w, h) = (60u32, 40u32);
    let keys = [(1024, 2), (2048, 4326)];
    let (path, _) = build_geotiff(
        dir.path(),
        "wgs84",
        (w, h),
        [8.0, 46.6],
        [cell, cell],
        &keys,
    );
    let reader = open(&path);
    let header = reader.header();
    let g = header.georef.as_ref().unwrap();
    assert_eq!((g.crs.as_str(), g.units), ("EPSG:4326", Units::Degrees));
    assert_eq!(g.first, (8.0 + cell / 2.0, 46.6 - cell / 2.0));
    assert_eq!(g.cell.1, cell);
    // Columns resampled to square cells: as much closer in degrees as they are in metres.
    let centre = (46.6 - cell / 2.0 - f64::from(h - 1) * cell / 2.0).to_radians();
    assert!(
        (g.cell.0 - cell / centre.cos()).abs() < 1e-15,
        "{}",
        g.cell.0
    );
    // The build's equirectangular metres at the centre latitude, from `database.md`.
    let metres = |lat: f64, lon: f64| (lon * 111_320.0 * centre.cos(), lat * 111_320.0);
    let (lat, lon) = (46.58, 8.02);
    let at = header.locate(lat, lon, "wgs84").unwrap();
    let (e, n) = metres(lat, lon);
    assert!((at.east - e).abs() < 1e-6 && (at.north - n).abs() < 1e-6);
    // 46 34.8' N, 8 01.2' E in NMEA is the same place.
    let gga = with_checksum("GNGGA,080000,4634.800,N,00801.200,E,2,12,0.6,1500,M,48.0,M,,");
    let feed = feed(dir.path(), &path, &[gga]);
    let (pose, _) = feed.at(0.0).unwrap();
    assert!((pose.east - e).abs() < 1e-6 && (pose.north - n).abs() < 1e-6);
    assert_eq!((pose.altitude, pose.heading), (1500.0, 0.0));
}

#[test]
fn archives_without_a_crs_have_the_fixed_header_and_refuse_latitudes_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let samples = (0..33 * 33).map(|k| (k % 33) as f32).collect();
    let reader = MemoryReader::new("plain", 33, 33, samples).unwrap();
    let out = dir.path().join("plain.smdb");
    let options = BuildOptions {
        tile_size: 33,
        ..BuildOptions::default()
    };
    build(NodataFill::new(reader, None), &out, &options, &|_, _| {}).unwrap();
    let bytes = std::fs::read(&out).unwrap();
    assert_eq!(bytes[12..16], (HEADER_LEN as u32).to_le_bytes());
    let archive = open(&out);
    assert_eq!(archive.header().georef, None);
    assert_eq!(archive.header().to_bytes(), bytes[..HEADER_LEN]);
    let e = archive
        .header()
        .locate(47.0, 8.0, "plain.smdb")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("plain.smdb") && e.contains("no georeferencing"),
        "{e}"
    );
    let engine = Engine::new(
        source::open(out.to_str().unwrap()).unwrap(),
        EngineSettings::default(),
        stripmask::Viewport::new(64, 48),
    )
    .unwrap();
    let e = engine.locate(47.0, 8.0, 0.0).unwrap_err().to_string();
    assert!(
        e.contains("plain.smdb") && e.contains("no georeferencing"),
        "{e}"
    );
    // A recording in latitude and longitude over it stops at its first such line.
    let recording = dir.path().join("gps.nmea");
    let lines = [
        "0 10 -10 500 0 0 0".to_string(),
        with_checksum("GPGGA,120001,4700.060,N,12259.760,W,1,09,0.8,2100.0,M,-22.0,M,,"),
    ];
    std::fs::write(&recording, lines.join("\n")).unwrap();
    let decoder = PoseDecoder::new("plain.smdb", archive.header().clone());
    let e = PoseFeed::open(&PoseSource::File(recording), decoder)
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("gps.nmea") && e.contains("line 2") && e.contains("plain.smdb"),
        "{e}"
    );
    // An ASCII grid placed by its corner alone, with no .prj to name a CRS, stores none.
    let corner_only = dir.path().join("corner.smdb");
    plain_archive(&corner_only);
    let bytes = std::fs::read(&corner_only).unwrap();
    assert_eq!(bytes[12..16], (HEADER_LEN as u32).to_le_bytes());
    let info = stripmask().arg("info").arg(&corner_only).output().unwrap();
    let text = String::from_utf8(info.stdout).unwrap();
    assert!(text.contains("crs         none stored"), "{text}");
    assert!(!text.contains("corners"), "{text}");
}

#[test]
fn info_prints_the_crs_and_the_corners() {
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = utm_archive(dir.path());
    let (x, y) = utm_first();
    let info = stripmask().arg("info").arg(&path).output().unwrap();
    let text = String::from_utf8(info.stdout).unwrap();
    assert!(
        text.contains("crs         EPSG:32610 (linear units of 1 m); 10 x 10 CRS units"),
        "{text}"
    );
    let corners = format!(
        "corners     NW ({x}, {y}), NE ({}, {y}), SW ({x}, {}), SE ({}, {})",
        x + 690.0,
        y - 490.0,
        x + 690.0,
        y - 490.0
    );
    assert!(text.contains(&corners), "{text}");
    let json = stripmask()
        .args(["info", "--json"])
        .arg(&path)
        .output()
        .unwrap();
    let v: serde_json::Value = serde_json::from_slice(&json.stdout).unwrap();
    assert_eq!(v["header"]["georef"]["crs"], "EPSG:32610");
    assert_eq!(v["corners"][0][0], x);
}

/// The UTM archive's whole header, built once.
fn utm_header() -> &'static (Vec<u8>, PathBuf, tempfile::TempDir) {
    static HEADER: std::sync::OnceLock<(Vec<u8>, PathBuf, tempfile::TempDir)> =
        std::sync::OnceLock::new();
    HEADER.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let (path, report) = utm_archive(dir.path());
        let bytes = std::fs::read(&path).unwrap();
        (bytes[..report.header.header_len()].to_vec(), path, dir)
    })
}

/// Restores the fixed part's and the georeferencing's checksums after an edit.
fn reseal(b: &mut [u8]) {
    let crc = crc32fast::hash(&b[..HEADER_LEN - 4]);
    b[HEADER_LEN - 4..HEADER_LEN].copy_from_slice(&crc.to_le_bytes());
    if b.len() > HEADER_LEN + 4 {
        let end = b.len() - 4;
        let crc = crc32fast::hash(&b[HEADER_LEN..end]);
        b[end..].copy_from_slice(&crc.to_le_bytes());
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Any bytes in the georeferencing, with or without repaired checksums, and any header
    /// length: the header is refused naming the archive or read, never a panic.
    #[test]
    fn damaged_georeferencing_is_refused_by_name(
        edits in proptest::collection::vec((0usize..80, any::<u8>()), 1..6),
        length in proptest::option::of(0u32..2000),
        fix in any::<bool>(),
    ) {
        let (good, path, _) = utm_header();
        let mut b = good.clone();
        for &(at, v) in &edits {
            let i = HEADER_LEN + at % (b.len() - HEADER_LEN);
            b[i] = v;
        }
        if let Some(len) = length {
            b[12..16].copy_from_slice(&len.to_le_bytes());
        }
        if fix {
            reseal(&mut b);
        }
        match Header::parse(&b, "fuzz.smdb") {
            Ok(h) if b == *good => prop_assert!(h.georef.is_some()),
            Ok(_) => {}
            Err(e) => prop_assert!(e.to_string().contains("fuzz.smdb"), "{}", e),
        }
        // The whole archive with that header opens or fails naming its file.
        let mut archive = std::fs::read(path).unwrap();
        archive[..b.len()].copy_from_slice(&b);
        let damaged = path.with_file_name("damaged.smdb");
        std::fs::write(&damaged, &archive).unwrap();
        if let Err(e) = ArchiveReader::open(FileSource::open(&damaged).unwrap()) {
            prop_assert!(e.to_string().contains("damaged.smdb"), "{}", e);
        }
    }

    /// Any line, NMEA-like or not: the decoder gives a reading or a refusal, never a panic,
    /// and a recording's refusal names the file and the line.
    #[test]
    fn any_feed_line_is_read_or_refused_by_line(
        line in prop_oneof![
            any::<String>(),
            "\\$[A-Z]{2}(GGA|RMC),[0-9.]{0,12},[AV0-9.]{0,10},[NS]?,[0-9.]{0,12},[EW]?,[0-9.,]{0,30}(\\*[0-9A-F]{2})?",
            "geo[ ,][-0-9., e]{0,60}",
            "[-0-9., eEnaif]{0,60}",
        ],
    ) {
        let line = line.replace(['\n', '\r'], " ");
        let (_, path, _) = utm_header();
        let header = open(path).header().clone();
        let mut decoder = PoseDecoder::new("fuzz.smdb", header.clone());
        let _ = decoder.line(&line);
        let _ = decoder.line(&with_checksum(line.trim_start_matches('$')));
        let dir = tempfile::tempdir().unwrap();
        let recording = dir.path().join("fuzz.txt");
        std::fs::write(&recording, format!("0 500000 5200000 900 0 0 0\n{line}\n")).unwrap();
        let decoder = PoseDecoder::new("fuzz.smdb", header);
        if let Err(e) = PoseFeed::open(&PoseSource::File(recording), decoder) {
            let e = e.to_string();
            prop_assert!(e.contains("fuzz.txt") && e.contains("line 2"), "{}", e);
        }
    }
}

#[test]
fn an_ascii_grid_takes_its_crs_from_the_prj_beside_it() {
    let dir = tempfile::tempdir().unwrap();
    let asc = dir.path().join("utm.asc");
    let mut text =
        "ncols 5\nnrows 4\nxllcorner 500000\nyllcorner 5200000\ncellsize 30\n".to_string();
    for j in 0..4 {
        let row: Vec<String> = (0..5).map(|i| height(i, j).to_string()).collect();
        text += &(row.join(" ") + "\n");
    }
    std::fs::write(&asc, text).unwrap();
    let wkt = r#"PROJCS["WGS 84 / UTM zone 10N",GEOGCS["WGS 84",AUTHORITY["EPSG","4326"]],PROJECTION["Transverse_Mercator"],PARAMETER["central_meridian",-123],UNIT["metre",1],AUTHORITY["EPSG","32610"]]"#;
    std::fs::write(dir.path().join("utm.prj"), format!("{wkt}\n")).unwrap();
    let out = dir.path().join("utm.smdb");
    let options = BuildOptions {
        tile_size: 5,
        ..BuildOptions::default()
    };
    build_file(&asc, &OpenOptions::default(), &out, &options, &|_, _| {}).unwrap();
    let g = open(&out).header().georef.clone().unwrap();
    assert_eq!(g.crs, "EPSG:32610");
    // The corner is the grid's south-west edge: the first sample's centre is half a cell in.
    assert_eq!(g.first, (500_015.0, 5_200_000.0 + 4.0 * 30.0 - 15.0));
}
