//! True distances and the inputs people have: grids in degrees get metres on both axes, an ASCII
//! grid in degrees is recognised, 8-bit PNG and JPEG height maps build, and a relief too tall for
//! the default height quantum gets one that fits.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use stripmask::db::grid::TileId;

use stripmask::ArchiveReader;
use stripmask::db::source::file::FileSource;

const METRES_PER_DEGREE: f64 = 111_320.0;

fn stripmask() -> Command {
    Command::new(env!("CARGO_BIN_EXE_stripmask"))
}

/// Runs `build` on `input` with `args` (33-sample tiles unless they say), into `input.smdb`.
fn build(input: &Path, args: &[&str]) -> (Output, PathBuf) {
    let out = input.with_extension("smdb");
    let tiles: &[&str] = if args.contains(&"--tile-size") {
        &[]
    } else {
        &["--tile-size", "33"]
    };
    let o = stripmask()
        .args(["build", "-o"])
        .arg(&out)
        .args(tiles)
        .args(args)
        .arg(input)
        .output()
        .unwrap();
    (o, out)
}

fn ok(o: &Output) -> String {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8(o.stdout.clone()).unwrap()
}

fn archive(path: &Path) -> ArchiveReader<FileSource> {
    ArchiveReader::open(FileSource::open(path).unwrap()).unwrap()
}

/// The height the archive holds at sample column `i` of row 0.
fn height_at(a: &ArchiveReader<FileSource>, i: usize) -> f32 {
    let s = a.header().tile_size as usize - 1;
    a.tile(TileId::new((i / s) as u32, 0))
        .unwrap()
        .unwrap()
        .height(i % s, 0)
}

/// Metres east-west per source column in the archive of a ramp rising `rise` raw units per
/// source column: a column's height says which source column it came from.
fn metres_per_source_column(a: &ArchiveReader<FileSource>, rise: f32) -> f64 {
    let k = a.header().source_width as usize - 1;
    let source_column = f64::from(height_at(a, k) - height_at(a, 0)) / f64::from(rise);
    k as f64 * a.header().spacing / source_column
}

/// An ESRI ASCII grid of `n x n` samples rising 10 units per column, with the given header lines.
fn ramp_asc(path: &Path, n: usize, header: &str) {
    let mut text = format!("ncols {n}\nnrows {n}\n{header}");
    for _ in 0..n {
        for i in 0..n {
            write!(text, "{} ", 10 * i).unwrap();
        }
        text.push('\n');
    }
    std::fs::write(path, text).unwrap();
}

#[test]
fn an_hgt_tile_at_fifty_degrees_north_is_true_east_west() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("N50E007.hgt");
    // 121 x 121 samples over one degree (30 arc-seconds), rising 10 m per column.
    let n = 121;
    let bytes: Vec<u8> = (0..n * n)
        .flat_map(|k| (10 * (k % n) as i16).to_be_bytes())
        .collect();
    std::fs::write(&path, bytes).unwrap();
    let (o, out) = build(&path, &[]);
    let text = ok(&o);
    let a = archive(&out);
    let cell = METRES_PER_DEGREE / 120.0;
    let cos = 50.5f64.to_radians().cos();
    assert!((a.header().spacing - cell).abs() < 1e-6);
    let east_west = metres_per_source_column(&a, 10.0);
    assert!(
        (east_west / (cell * cos) - 1.0).abs() < 0.01,
        "{east_west} vs {}",
        cell * cos
    );
    assert!((a.header().origin_y - 51.0 * METRES_PER_DEGREE).abs() < 1.0);
    assert!((a.header().origin_x - 7.0 * METRES_PER_DEGREE * cos).abs() < 1.0);
    assert!(
        text.contains("geographic grid") && text.contains("spacing"),
        "{text}"
    );
}

#[test]
fn a_geographic_geotiff_builds_with_metres_on_both_axes() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/geographic.tif");
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("geographic.tif");
    std::fs::copy(path, &input).unwrap();
    let (o, out) = build(&input, &[]);
    ok(&o);
    let a = archive(&out);
    // 37 x 29 samples over 1 x 1 degree centred at 47°N: square cells of 1/29 degree of
    // latitude, 36 cells of 1/37 degree of longitude east-west.
    let h = a.header();
    assert!((h.spacing - METRES_PER_DEGREE / 29.0).abs() < 1e-6);
    let east_west = 36.0 / 37.0 * METRES_PER_DEGREE * 47f64.to_radians().cos();
    let extent = (h.source_width - 1) as f64 * h.spacing;
    assert!(
        extent <= east_west && extent > east_west - h.spacing,
        "{extent} vs {east_west}"
    );
    assert!(h.origin_y > 47.0 * METRES_PER_DEGREE, "{}", h.origin_y);
    assert!(h.origin_x < -80.0 * METRES_PER_DEGREE, "{}", h.origin_x);
}

#[test]
fn an_ascii_grid_in_degrees_is_recognised() {
    let dir = tempfile::tempdir().unwrap();
    let placed = dir.path().join("placed.asc");
    ramp_asc(
        &placed,
        65,
        "xllcorner 7.0\nyllcorner 49.98\ncellsize 0.000833333\n",
    );
    let (o, out) = build(&placed, &[]);
    let text = ok(&o);
    assert!(text.contains("taken as degrees"), "{text}");
    let a = archive(&out);
    let cell = 0.000_833_333 * METRES_PER_DEGREE;
    assert!(
        (a.header().spacing - cell).abs() < 1e-3,
        "{}",
        a.header().spacing
    );
    let latitude: f64 = 49.98 + 32.5 * 0.000_833_333;
    let east_west = metres_per_source_column(&a, 10.0);
    let want = cell * latitude.to_radians().cos();
    assert!(
        (east_west / want - 1.0).abs() < 0.01,
        "{east_west} vs {want}"
    );

    // Without a corner on Earth the build cannot know the latitude: it asks for --spacing.
    let lost = dir.path().join("lost.asc");
    ramp_asc(&lost, 9, "cellsize 0.0002\n");
    let (o, _) = build(&lost, &[]);
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("lost.asc") && err.contains("degrees") && err.contains("--spacing"),
        "{err}"
    );
    let (o, out) = build(&lost, &["--spacing", "25"]);
    ok(&o);
    assert_eq!(archive(&out).header().spacing, 25.0);
}

#[test]
fn eight_bit_png_and_jpeg_height_maps_build_with_a_vertical_scale() {
    let dir = tempfile::tempdir().unwrap();
    // A gray ramp in flat bands 8 pixels wide (JPEG keeps flat blocks exact).
    let value = |x: u32| (x / 8 * 30) as u8;
    let gray = image::GrayImage::from_fn(65, 65, |x, _| image::Luma([value(x)]));
    let rgb = image::RgbImage::from_fn(65, 65, |x, _| image::Rgb([value(x); 3]));
    let inputs = [
        ("gray.png", image::DynamicImage::ImageLuma8(gray.clone())),
        ("rgb.png", image::DynamicImage::ImageRgb8(rgb.clone())),
        ("gray.jpg", image::DynamicImage::ImageLuma8(gray)),
        ("rgb.jpeg", image::DynamicImage::ImageRgb8(rgb)),
    ];
    for (name, img) in inputs {
        let path = dir.path().join(name);
        img.save(&path).unwrap();
        let (o, out) = build(&path, &["--vertical-scale", "2.5"]);
        let text = ok(&o);
        assert!(text.contains("8-bit samples"), "{name}: {text}");
        let a = archive(&out);
        let want = f32::from(value(64)) * 2.5;
        let top = a.header().max_height;
        assert!((top - want).abs() <= 2.5 * 2.0, "{name}: {top} vs {want}");
        assert!(
            (height_at(&a, 20) - 2.5 * 60.0).abs() <= 2.5 * 2.0,
            "{name}"
        );
    }

    // A colour image is not a height map: the error says which pixel.
    let colour = dir.path().join("colour.png");
    image::RgbImage::from_fn(9, 9, |x, y| image::Rgb([x as u8, y as u8, 0]))
        .save(&colour)
        .unwrap();
    let (o, _) = build(&colour, &[]);
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("colour.png") && err.contains("pixel (1, 0)"),
        "{err}"
    );
}

#[test]
fn the_format_hint_lists_every_format() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("heights.dem");
    std::fs::write(&path, [0u8; 8]).unwrap();
    let (o, _) = build(&path, &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    for format in ["png", "jpeg", "tiff", "hgt", "asc", "raw"] {
        assert!(err.contains(format), "{format}: {err}");
    }
    let (o, _) = build(&path, &["--format", "bmp"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("jpeg"), "{err}");
}

#[test]
fn a_relief_too_tall_for_the_default_quantum_gets_one_that_fits() {
    let puget =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/data/puget_sound_1k_height.png");
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("puget.png");
    std::fs::copy(puget, &input).unwrap();
    // Raw units as metres: up to 43798 m, far more than 65535 sixteenths of a metre.
    let (o, out) = build(&input, &["--tile-size", "129"]);
    let text = ok(&o);
    let q = archive(&out).header().height_quantum;
    assert!(q > 0.0625 && (q / 0.0625).log2().fract() == 0.0, "{q}");
    assert!(text.contains(&format!("height quantum {q} m")), "{text}");
    // A quantum the user chose is kept, and refused when it does not fit.
    let (o, _) = build(
        &input,
        &["--tile-size", "129", "--height-quantum", "0.0625"],
    );
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("larger height quantum"));
}
