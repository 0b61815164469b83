//! Lit views show no line along tile borders: the luminance second difference across a tile
//! border is within 1.2x of its value inside the tiles, on a real model (Puget Sound) and on a
//! smooth synthetic surface, top-down and oblique; and tiles holding the same level, whole or
//! partial, light the vertices they share alike.
//!
//! `cargo test --profile ci --test it seams -- --nocapture` prints the ratios docs/cracks.md
//! quotes.

use std::path::{Path, PathBuf};

use glam::{DVec3, DVec4};
use stripmask::db::archive::ArchiveReader;
use stripmask::db::builder::{BuildOptions, build};
use stripmask::db::dem::{self, MemoryReader, NodataFill, OpenOptions};
use stripmask::db::source;
use stripmask::db::source::file::FileSource;
use stripmask::db::tile::PartialGrid;
use stripmask::engine::camera::Camera;
use stripmask::engine::cracks::CrackMode;
use stripmask::engine::paging::PagerMode;
use stripmask::engine::resident::{Light, ResidentTile};
use stripmask::engine::{Engine, EngineSettings};
use stripmask_raster::{ColorFormat, DepthBuffer, DepthFormat, Framebuffer};

const WIDTH: u32 = 480;
const HEIGHT: u32 = 360;

/// The Puget Sound model (1025², 160 m apart) in tiles of 65 samples: 16 x 16 tiles of 10 km.
fn puget(dir: &Path) -> PathBuf {
    let input =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/data/puget_sound_1k_height.png");
    let open = OpenOptions {
        format: None,
        raw: None,
        nodata: None,
    };
    let out = dir.join("puget.smdb");
    let options = BuildOptions {
        tile_size: 65,
        spacing: Some(160.0),
        vertical_scale: 0.1,
        ..BuildOptions::default()
    };
    build(
        dem::open(&input, &open).unwrap(),
        &out,
        &options,
        &|_, _| {},
    )
    .unwrap();
    out
}

/// A smooth surface of long swells, 257², 30 m apart, in tiles of 33 samples (8 x 8 tiles).
fn swells(dir: &Path) -> PathBuf {
    let n = 257;
    let samples = (0..n * n)
        .map(|k| {
            let (x, z) = ((k % n) as f32, (k / n) as f32);
            300.0 + 120.0 * (x / 23.0).sin() * (z / 31.0).cos() + 40.0 * ((x + z) / 17.0).sin()
        })
        .collect();
    let reader = MemoryReader::new("swells", n, n, samples).unwrap();
    let out = dir.join("swells.smdb");
    let options = BuildOptions {
        tile_size: 33,
        spacing: Some(30.0),
        ..BuildOptions::default()
    };
    build(NodataFill::new(reader, None), &out, &options, &|_, _| {}).unwrap();
    out
}

/// Every tile whole and drawn at mask level 0, so that what differs at a border is the lighting
/// alone, not two levels meeting.
fn engine(path: &Path) -> Engine {
    let settings = EngineSettings {
        memory_limit_bytes: 512 << 20,
        pager_mode: PagerMode::Stepped {
            fetches_per_update: 1024,
        },
        threads: 1,
        ..EngineSettings::default()
    };
    let mut engine =
        Engine::new(source::open(path.to_str().unwrap()).unwrap(), settings, 120).unwrap();
    engine.force_levels(Some(Box::new(|_| 0)));
    // The vertex lighting alone: a bilinear texture bends at its texel centres, and the border
    // is one (the edge texels lie on it) where the line halfway across a tile is not, so with
    // texels several pixels wide the texture alone tells the lines apart; its border texels are
    // equal in both tiles (`texture_gen`'s tests).
    engine.render_settings_mut().sampler = None;
    engine
}

/// The view from `eye` to `target`, rendered until every tile in it is loaded; returns the
/// frame and the camera it was drawn with.
fn view(engine: &mut Engine, eye: DVec3, target: DVec3) -> (Framebuffer, Camera) {
    let mut fb = Framebuffer::new(WIDTH, HEIGHT, ColorFormat::Rgba8888, DepthFormat::D32).unwrap();
    let mut drawn = None;
    for k in 0..30 {
        engine.set_time(f64::from(k));
        let camera = engine.camera(eye, target, false);
        let report = engine.render(&camera, &mut fb).unwrap();
        assert!(report.rendered_tiles > 0);
        let settled = report.pager.fetching == 0 && report.holes == 0;
        drawn = Some(report.camera);
        if settled && k > 3 {
            break;
        }
    }
    (fb, drawn.unwrap())
}

/// Mean absolute luminance second difference at pixels whose two neighbours (along a screen
/// row or column) lie on two sides of a tile border, and at pixels whose neighbours lie on two
/// sides of a line through the middle of a tile (the sample column or row halfway across it):
/// lines of the same kind, spacing and distance from the eye, one between tiles, one inside
/// them. Tiles are `cells` cells of `spacing` metres from the world origin; a pixel's place on
/// the ground comes from its depth.
fn second_differences(
    fb: &Framebuffer,
    camera: &Camera,
    spacing: f64,
    cells: i64,
) -> (f64, f64, usize) {
    let (w, h) = (WIDTH as usize, HEIGHT as usize);
    let DepthBuffer::D32(depth) = fb.depth() else {
        panic!("a 32-bit depth buffer")
    };
    let unproject = camera
        .view_projection(f64::from(WIDTH) / f64::from(HEIGHT))
        .inverse();
    let cell = |x: usize, y: usize| -> Option<(i64, i64)> {
        let d = depth[y * w + x];
        (d != u32::MAX).then(|| {
            let ndc = DVec4::new(
                2.0 * (x as f64 + 0.5) / w as f64 - 1.0,
                1.0 - 2.0 * (y as f64 + 0.5) / h as f64,
                f64::from(d) / 4_294_967_296.0,
                1.0,
            );
            let p = unproject * ndc;
            let world = p.truncate() / p.w + camera.position;
            (
                (world.x / spacing).floor() as i64,
                (world.z / spacing).floor() as i64,
            )
        })
    };
    let tile = |c: (i64, i64)| (c.0.div_euclid(cells), c.1.div_euclid(cells));
    let half = |c: (i64, i64)| tile((c.0 + cells / 2, c.1 + cells / 2));
    let luminance = |x: usize, y: usize| {
        let [r, g, b] = fb.pixel(x as u32, y as u32);
        0.299 * f64::from(r) + 0.587 * f64::from(g) + 0.114 * f64::from(b)
    };
    let (mut border, mut interior) = ((0.0, 0usize), (0.0, 0usize));
    for y in 2..h - 2 {
        for x in 2..w - 2 {
            for (dx, dy) in [(1isize, 0isize), (0, 1)] {
                let at = |k: isize| {
                    let (px, py) = (
                        (x as isize + k * dx) as usize,
                        (y as isize + k * dy) as usize,
                    );
                    cell(px, py).map(|c| (c, luminance(px, py)))
                };
                let Some(line) = (-2..=2).map(at).collect::<Option<Vec<_>>>() else {
                    continue;
                };
                let d2 = (line[1].1 - 2.0 * line[2].1 + line[3].1).abs();
                if tile(line[1].0) != tile(line[3].0) {
                    border.0 += d2;
                    border.1 += 1;
                } else if half(line[1].0) != half(line[3].0) {
                    interior.0 += d2;
                    interior.1 += 1;
                }
            }
        }
    }
    assert!(
        border.1 > 200 && interior.1 > border.1 / 2,
        "{border:?} {interior:?}"
    );
    (
        border.0 / border.1 as f64,
        interior.0 / interior.1 as f64,
        border.1,
    )
}

/// Asserts that the lit top-down and oblique views of `path`, whose tiles are `cells` cells of
/// `spacing` metres, centred on `centre` and `height` metres above it, have a border-to-interior
/// ratio of at most 1.2.
fn assert_no_seams(path: &Path, spacing: f64, cells: i64, centre: DVec3, height: f64) {
    let mut engine = engine(path);
    let views = [
        (centre + DVec3::new(0.0, height, 0.0), centre),
        (
            centre + DVec3::new(-0.4 * height, 0.6 * height, 1.4 * height),
            centre,
        ),
    ];
    for (eye, target) in views {
        let (fb, camera) = view(&mut engine, eye, target);
        let (border, interior, pixels) = second_differences(&fb, &camera, spacing, cells);
        let ratio = border / interior;
        println!(
            "{}: eye {eye:.0}: border {border:.3} over {pixels} px, interior {interior:.3}, \
             ratio {ratio:.3}",
            path.display()
        );
        assert!(ratio <= 1.2, "eye {eye:.0}: border/interior {ratio:.3}");
    }
}

#[test]
fn lit_views_of_a_real_model_show_no_line_along_tile_borders() {
    let dir = tempfile::tempdir().unwrap();
    // 64 cells of 160 m per tile; the view spans about three tiles across.
    let tile = 64.0 * 160.0;
    let centre = DVec3::new(5.5 * tile, 0.0, 7.5 * tile);
    assert_no_seams(&puget(dir.path()), 160.0, 64, centre, 26_000.0);
}

#[test]
fn lit_views_of_a_smooth_surface_show_no_line_along_tile_borders() {
    let dir = tempfile::tempdir().unwrap();
    let tile = 32.0 * 30.0;
    let centre = DVec3::new(4.5 * tile, 300.0, 3.5 * tile);
    assert_no_seams(&swells(dir.path()), 30.0, 32, centre, 2_800.0);
}
#[test]
fn neighbours_holding_the_same_level_light_their_shared_border_alike() {
    let dir = tempfile::tempdir().unwrap();
    let path = puget(dir.path());
    let archive = ArchiveReader::open(FileSource::open(&path).unwrap()).unwrap();
    let resident = |tx, ty, levels| {
        let tile = archive.tile(tx, ty).unwrap().truncated(levels);
        ResidentTile::new(&tile, 0, 160.0, &Light::default(), CrackMode::None)
    };
    for levels in 1..=7 {
        let (west, east, south) = (
            resident(5, 7, levels),
            resident(6, 7, levels),
            resident(5, 8, levels),
        );
        let side = west.side();
        for k in 0..side {
            let n = |t: &ResidentTile, i: usize, j: usize| t.normals[j * side + i];
            assert_eq!(
                n(&west, side - 1, k),
                n(&east, 0, k),
                "{levels} levels, row {k}"
            );
            assert_eq!(
                n(&west, k, side - 1),
                n(&south, k, 0),
                "{levels} levels, column {k}"
            );
            let lit = |t: &ResidentTile, i: usize, j: usize| t.vertices[j * side + i].color;
            assert_eq!(lit(&west, side - 1, k), lit(&east, 0, k));
        }
    }
}
