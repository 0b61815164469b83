//! The engine at numerical extremes, on small synthetic archives: heights from the ocean floor
//! (−11,000 m) to Everest (+9,000 m), cliffs of the full 16-bit height range beside flat tiles,
//! the eye a centimetre above the ground, views grazing 0.1° above the horizon, a 1 mm near
//! plane with a 10^6 m far plane, triangles far larger than the screen and far smaller than a
//! pixel, the terrain 10^3..10^8 m from the origin, and frames from 1x1 to 4096x4096.
//!
//! Nothing may panic or wrap (the `ci` profile keeps overflow checks on), no report value may be
//! NaN, and the fixed-point path must stay within [`FIXED_VS_FLOAT`] of the f32 path. Depth
//! order is checked against the resolution of each depth format, and the test computes and
//! asserts where each one stops resolving. (`raster/tests/it/extremes.rs` covers the rasterizer
//! alone with raw matrices; these go through the engine's tiles, masks and transforms.)

use std::path::{Path, PathBuf};

use glam::DVec3;
use image::RgbaImage;
use stripmask::db::builder::{BuildOptions, build};
use stripmask::db::dem::{MemoryReader, NodataFill};
use stripmask::db::source;
use stripmask::engine::camera::{Camera, View};
use stripmask::engine::cracks::{CrackMode, TileIndices};
use stripmask::engine::paging::PagerMode;
use stripmask::engine::render::{RenderSettings, TileDraw, TileMeshes, draw_tiles};
use stripmask::engine::viewport::Viewport;
use stripmask::engine::{Engine, EngineSettings, FrameReport, FrameTiming};
use stripmask::sim::tradeoff::metrics::{compare, psnr};
use stripmask_raster::{
    ColorFormat, DepthFormat, DrawStats, Framebuffer, Precision, RasterTarget, Rasterizer,
};

/// How far the fixed-point path may stray from the f32 path on the same frame: at most this
/// fraction of pixels may differ by more than [`OFF`] in a channel, and PSNR stays at or above
/// [`MIN_PSNR_DB`]. Both pipelines share the sub-pixel grid and coverage rule; what differs is
/// attribute rounding (colour, texel coordinates, fog) and depth ties.
const FIXED_VS_FLOAT: f64 = 0.01;
const OFF: u8 = 24;
const MIN_PSNR_DB: f64 = 30.0;

/// Builds an archive of `w x h` samples from `height(i, j)` metres in `dir`.
fn archive(
    dir: &Path,
    name: &str,
    (w, h): (usize, usize),
    tile_size: usize,
    spacing: f64,
    quantum: f32,
    height: impl Fn(usize, usize) -> f32,
) -> PathBuf {
    let samples = (0..w * h).map(|k| height(k % w, k / w)).collect();
    let reader = MemoryReader::new(name, w, h, samples).unwrap();
    let out = dir.join(format!("{name}.smdb"));
    let options = BuildOptions {
        tile_size,
        spacing: Some(spacing),
        height_quantum: Some(quantum),
        texture_factor: 2,
        ..BuildOptions::default()
    };
    build(NodataFill::new(reader, None), &out, &options, &|_, _| {}).unwrap();
    out
}

/// An engine over `path` with every tile loaded, one thread, levels pinned to full resolution.
fn engine(path: &Path, size: (u32, u32), clearance: f64) -> Engine {
    let settings = EngineSettings {
        memory_limit_bytes: 1 << 30,
        pager_mode: PagerMode::Stepped {
            fetches_per_update: 4096,
        },
        threads: 1,
        clearance,
        frame_timing: FrameTiming::Told,
        ..EngineSettings::default()
    };
    let mut engine = Engine::new(
        source::open(path.to_str().unwrap()).unwrap(),
        settings,
        Viewport::new(size.0, size.1),
    )
    .unwrap();
    engine.force_levels(Some(Box::new(|_| 0)));
    let mut fb = Framebuffer::new(size.0, size.1, ColorFormat::Rgba8888, DepthFormat::D16).unwrap();
    let terrain = *engine.terrain();
    let (w, d) = terrain.extent();
    let centre = DVec3::new(w / 2.0, terrain.heights.1 + 10.0, d / 2.0);
    let camera = engine.camera(centre, centre + DVec3::new(1.0, -1.0, 0.0), false);
    engine.render(&camera, &mut fb).unwrap();
    let loaded = engine.pager().stats().loaded_tiles;
    assert_eq!(loaded, (terrain.tiles_x * terrain.tiles_y) as usize);
    engine
}

/// One frame through the engine in `precision`.
fn frame(
    engine: &mut Engine,
    camera: &Camera,
    size: (u32, u32),
    precision: Precision,
    depth: DepthFormat,
) -> (RgbaImage, FrameReport) {
    engine.render_settings_mut().precision = precision;
    let mut fb = Framebuffer::new(size.0, size.1, ColorFormat::Rgba8888, depth).unwrap();
    let report = engine.render(camera, &mut fb).unwrap();
    check_report(&report);
    (fb.to_rgba_image(), report)
}

/// No NaN anywhere in a frame's report; importances sum to 1.
fn check_report(r: &FrameReport) {
    let v = &r.view;
    assert!(
        v.camera.position.is_finite() && v.camera.forward.is_finite(),
        "{v:?}"
    );
    assert!(
        v.near.is_finite() && v.far.is_finite() && 0.0 < v.near && v.near < v.far,
        "{v:?}"
    );
    let sum: f64 = r.rendered.iter().map(|t| t.importance).sum();
    assert!(
        r.rendered
            .iter()
            .all(|t| t.importance.is_finite() && t.importance >= 0.0)
    );
    assert!(
        r.rendered.is_empty() || (sum - 1.0).abs() < 1e-9,
        "importances sum to {sum}"
    );
    assert!(r.bookkeeping_seconds.is_finite() && r.draw_seconds.is_finite());
}

/// Renders `camera`'s view in both pipelines and asserts they agree within [`FIXED_VS_FLOAT`];
/// returns the fixed frame and its report.
fn fixed_matches_float(
    engine: &mut Engine,
    camera: &Camera,
    size: (u32, u32),
    what: &str,
) -> (RgbaImage, FrameReport) {
    let (fixed, report) = frame(engine, camera, size, Precision::Fixed, DepthFormat::D32);
    let (float, _) = frame(engine, camera, size, Precision::Float, DepthFormat::D32);
    let e = compare(&fixed, &float, OFF);
    let off = e.pixels_off as f64 / e.pixels as f64;
    println!(
        "{what}: {:.3}% off, PSNR {:.1} dB, SSIM {:.4}",
        100.0 * off,
        psnr(e.mse),
        e.ssim
    );
    assert!(
        off <= FIXED_VS_FLOAT,
        "{what}: {:.3}% of pixels off by > {OFF}",
        100.0 * off
    );
    assert!(
        psnr(e.mse) >= MIN_PSNR_DB,
        "{what}: PSNR {:.1} dB",
        psnr(e.mse)
    );
    (fixed, report)
}

fn sky_pixels(image: &RgbaImage) -> usize {
    let sky = RenderSettings::default().sky;
    image.pixels().filter(|p| p.0[..3] == sky).count()
}

/// A trench to −11,000 m and a peak at +9,000 m in one 33 x 33 model (2 x 2 tiles of 17),
/// 500 m apart; a 0.5 m quantum lets one tile hold the 20 km of relief.
fn ocean_to_everest(dir: &Path) -> PathBuf {
    archive(dir, "ocean-to-everest", (33, 33), 17, 500.0, 0.5, |i, j| {
        let (x, z) = (i as f32 - 8.0, j as f32 - 20.0);
        let trench = -11_000.0 * (-(x * x + z * z) / 30.0).exp();
        let (x, z) = (i as f32 - 24.0, j as f32 - 10.0);
        let peak = 9_000.0 * (-(x * x + z * z) / 20.0).exp();
        trench + peak
    })
}

#[test]
fn heights_from_the_ocean_floor_to_everest_keep_their_range_and_render_alike() {
    let dir = tempfile::tempdir().unwrap();
    let mut engine = engine(&ocean_to_everest(dir.path()), (160, 120), 20.0);
    let terrain = *engine.terrain();
    let (lo, hi) = terrain.heights;
    assert!(
        (lo + 11_000.0).abs() < 30.0 && (hi - 9_000.0).abs() < 30.0,
        "{lo} .. {hi}"
    );
    let lowest = engine
        .pager()
        .tiles()
        .map(|(_, t)| t.min)
        .fold(f32::MAX, f32::min);
    let highest = engine
        .pager()
        .tiles()
        .map(|(_, t)| t.max)
        .fold(f32::MIN, f32::max);
    assert!((f64::from(lowest) - lo).abs() <= 0.25 && (f64::from(highest) - hi).abs() <= 0.25);
    let views = [
        // From high above, the whole model.
        (
            DVec3::new(8000.0, 40_000.0, 24_000.0),
            DVec3::new(8000.0, 0.0, 7000.0),
        ),
        // Into the trench from its rim, and up at the peak from its foot.
        (
            DVec3::new(1000.0, 500.0, 14_000.0),
            DVec3::new(4000.0, -11_000.0, 10_000.0),
        ),
        (
            DVec3::new(12_000.0, 200.0, 9_000.0),
            DVec3::new(12_000.0, 9_000.0, 5_000.0),
        ),
    ];
    for (k, (eye, target)) in views.into_iter().enumerate() {
        let camera = engine.camera(eye, target, false);
        let (image, report) =
            fixed_matches_float(&mut engine, &camera, (160, 120), &format!("view {k}"));
        assert!(
            report.rendered_tiles > 0 && sky_pixels(&image) < 160 * 120,
            "view {k}"
        );
    }
}

#[test]
fn extreme_heights_far_from_the_origin_draw_the_same_bytes_in_both_pipelines() {
    let dir = tempfile::tempdir().unwrap();
    let path = ocean_to_everest(dir.path());
    // Dyadic positions, so that adding 10^3 .. 10^8 m is exact.
    let (eye, target) = (
        DVec3::new(2000.5, 12_000.25, 15_000.75),
        DVec3::new(9000.0, 0.0, 6000.0),
    );
    for precision in [Precision::Fixed, Precision::Float] {
        let mut pictures = Vec::new();
        for offset in [0.0, 1e3, 1e5, 1e7, 1e8] {
            let mut engine = engine(&path, (128, 96), 20.0);
            engine.place_terrain(DVec3::new(offset, offset / 4.0, -offset));
            let origin = engine.terrain().origin;
            let camera = engine.camera(origin + eye, origin + target, false);
            let (image, _) = frame(&mut engine, &camera, (128, 96), precision, DepthFormat::D32);
            pictures.push((offset, image));
        }
        for (offset, p) in &pictures[1..] {
            assert!(
                p == &pictures[0].1,
                "{precision:?}: offset {offset} changed the picture"
            );
        }
    }
}

#[test]
fn full_16_bit_cliffs_beside_flat_tiles() {
    let dir = tempfile::tempdir().unwrap();
    // 3 x 3 tiles of 9 samples, 50 m apart, at the default 1/16 m quantum. The middle column of
    // tiles holds a cliff of 65535 quanta between two neighbouring samples (the most a tile
    // can hold); every other tile is flat at the cliff's foot (zero relief: importance by
    // height must not divide by zero).
    let cliff = 65_535.0 / 16.0;
    let path = archive(dir.path(), "cliffs", (25, 25), 9, 50.0, 0.0625, |i, j| {
        if (12..=15).contains(&i) && (10..=14).contains(&j) {
            cliff
        } else {
            0.0
        }
    });
    let mut engine = engine(&path, (160, 120), 20.0);
    let flat = engine
        .pager()
        .tiles()
        .filter(|(_, t)| t.min == t.max)
        .count();
    assert_eq!(flat, 8, "eight flat tiles");
    let (_, quanta) = engine
        .pager()
        .tiles()
        .map(|(id, t)| {
            (
                id,
                t.vertices.iter().map(|v| v.position[1]).max().unwrap()
                    - t.vertices.iter().map(|v| v.position[1]).min().unwrap(),
            )
        })
        .max_by_key(|p| p.1)
        .unwrap();
    assert_eq!(quanta, 65_535, "the cliff spans the full 16-bit range");
    let views = [
        // Along the foot of the cliff, at the flat tiles and the wall.
        (
            DVec3::new(100.0, 30.0, 1150.0),
            DVec3::new(600.0, 500.0, 500.0),
        ),
        // From above the cliff's top, down its face.
        (
            DVec3::new(500.0, 4500.0, 600.0),
            DVec3::new(620.0, 0.0, 600.0),
        ),
        // Only flat tiles in view.
        (
            DVec3::new(200.0, 100.0, 1100.0),
            DVec3::new(100.0, 0.0, 1000.0),
        ),
    ];
    for (k, (eye, target)) in views.into_iter().enumerate() {
        let camera = engine.camera(eye, target, false);
        fixed_matches_float(&mut engine, &camera, (160, 120), &format!("cliff view {k}"));
    }
}

/// A gently rolling 65 x 65 model, 30 m apart (2 x 2 tiles of 33).
fn rolling(dir: &Path) -> PathBuf {
    archive(dir, "rolling", (65, 65), 33, 30.0, 0.0625, |i, j| {
        200.0 + 20.0 * (i as f32 * 0.2).sin() * (j as f32 * 0.15).cos()
    })
}

#[test]
fn the_eye_a_centimetre_above_the_ground_looking_0_1_degrees_above_the_horizon() {
    let dir = tempfile::tempdir().unwrap();
    let mut engine = engine(&rolling(dir.path()), (160, 120), 0.005);
    let eye = DVec3::new(960.0, 0.01, 960.0);
    for degrees in [0.1f64, 0.0, -0.1] {
        let ahead = DVec3::new(1.0, degrees.to_radians().tan(), 0.3).normalize();
        let camera = engine.camera(eye, eye + ahead * 1000.0, true);
        let ground = engine.ground(camera.position).unwrap();
        assert!(
            (camera.position.y - ground - 0.01).abs() < 1e-6,
            "1 cm above the ground"
        );
        let (image, report) = fixed_matches_float(
            &mut engine,
            &camera,
            (160, 120),
            &format!("grazing {degrees}°"),
        );
        assert!(report.rendered_tiles > 0);
        // The ground fills the bottom rows, the sky the top rows.
        let row_sky = |y: u32| {
            (0..160)
                .filter(|&x| image.get_pixel(x, y).0[..3] == RenderSettings::default().sky)
                .count()
        };
        assert_eq!(row_sky(119), 0, "{degrees}°: bottom row is ground");
        assert_eq!(row_sky(0), 160, "{degrees}°: top row is sky");
    }
}

/// Draws every loaded tile of `engine` at level 0 in `view` as it is (its own field of view and
/// depth planes, which `Engine::render` would take from the engine), in `precision` with `depth`.
fn draw_as_is(
    engine: &Engine,
    view: &View,
    precision: Precision,
    depth: DepthFormat,
) -> (Framebuffer, DrawStats) {
    let terrain = engine.terrain();
    let mut tiles: Vec<TileDraw<'_>> = engine
        .pager()
        .tiles()
        .map(|(id, tile)| {
            let (lo, hi) = terrain.tile_box(id, f64::from(tile.min), f64::from(tile.max));
            TileDraw {
                id,
                tile,
                level: 0,
                neighbours: [0; 4],
                distance: (((lo + hi) / 2.0) - view.camera.position).length(),
            }
        })
        .collect();
    let settings = RenderSettings {
        precision,
        fog: false,
        ..RenderSettings::default()
    };
    let mut cracks = TileIndices::new(CrackMode::None, terrain.tile_size);
    let (w, h) = (view.viewport.width, view.viewport.height);
    let mut fb = Framebuffer::new(w, h, ColorFormat::Rgba8888, depth).unwrap();
    let stats = draw_tiles(
        &mut RasterTarget::new(&mut fb, &mut Rasterizer::with_threads(1)),
        view,
        terrain,
        &mut tiles,
        TileMeshes {
            masks: engine.masks(),
            cracks: &mut cracks,
            partial: None,
            morph: None,
        },
        &settings,
    )
    .unwrap();
    (fb, stats.triangles)
}

#[test]
fn a_1_mm_near_plane_and_a_10_6_m_far_plane_over_triangles_kilometres_wide() {
    let dir = tempfile::tempdir().unwrap();
    // One tile of 17 samples 10 km apart: seen from a metre up, each triangle is many times
    // wider than the guard band.
    let path = archive(
        dir.path(),
        "huge",
        (17, 17),
        17,
        10_000.0,
        0.0625,
        |i, j| 100.0 + 50.0 * ((i + j) % 3) as f32,
    );
    let engine = engine(&path, (160, 120), 0.5);
    let eye = DVec3::new(80_000.0, 0.0, 80_000.0);
    let ground = engine.ground(eye).unwrap();
    for (k, target) in [DVec3::new(1.0, -0.05, 0.2), DVec3::new(0.0, -1.0, 0.001)]
        .into_iter()
        .enumerate()
    {
        let camera = Camera::looking_at(
            eye + DVec3::Y * (ground + 1.0),
            eye + DVec3::Y * (ground + 1.0) + target,
        );
        let view = View::new(camera, Viewport::new(160, 120), 1e-3, 1e6);
        let (fixed, s_fixed) = draw_as_is(&engine, &view, Precision::Fixed, DepthFormat::D32);
        let (float, s_float) = draw_as_is(&engine, &view, Precision::Float, DepthFormat::D32);
        assert!(
            s_fixed.rasterized > 0 && s_fixed.fragments > 0,
            "view {k}: {s_fixed:?}"
        );
        assert_eq!(s_fixed.triangles, s_float.triangles);
        let e = compare(&fixed.to_rgba_image(), &float.to_rgba_image(), OFF);
        let off = e.pixels_off as f64 / e.pixels as f64;
        println!(
            "huge view {k}: {:.3}% off, PSNR {:.1}",
            100.0 * off,
            psnr(e.mse)
        );
        assert!(
            off <= FIXED_VS_FLOAT && psnr(e.mse) >= MIN_PSNR_DB,
            "view {k}: {off}"
        );
        // Looking down from a metre, the ground fills the screen.
        if k == 1 {
            assert_eq!(sky_pixels(&fixed.to_rgba_image()), 0);
        }
    }
}

#[test]
fn sub_pixel_triangles_of_a_terrain_seen_from_afar() {
    let dir = tempfile::tempdir().unwrap();
    // 1 m between samples, seen from 2 km: a triangle is about 1/20 of a pixel, the whole
    // model a few.
    let path = archive(dir.path(), "tiny", (65, 65), 33, 1.0, 0.0625, |i, j| {
        ((i * 7 + j * 3) % 5) as f32
    });
    let mut engine = engine(&path, (160, 120), 20.0);
    let camera = engine.camera(
        DVec3::new(32.0, 1_200.0, 1_600.0),
        DVec3::new(32.0, 0.0, 32.0),
        false,
    );
    for precision in [Precision::Fixed, Precision::Float] {
        let (image, report) = frame(
            &mut engine,
            &camera,
            (160, 120),
            precision,
            DepthFormat::D16,
        );
        let covered = 160 * 120 - sky_pixels(&image);
        // The cut draws the model's one root tile (the pyramid's 2 x 2 tiles of 33 samples at
        // twice the spacing) at its finest mask: 2,048 triangles on a few pixels.
        assert!(
            report.draw.triangles >= 2048,
            "{precision:?}: {:?}",
            report.draw
        );
        assert!(
            (1..=16).contains(&covered),
            "{precision:?}: the model covers {covered} pixels"
        );
    }
}

#[test]
fn frames_from_1x1_to_4096x4096() {
    let dir = tempfile::tempdir().unwrap();
    let path = rolling(dir.path());
    for (w, h) in [(1, 1), (1, 9), (9, 1), (2, 2), (320, 240), (4096, 4096)] {
        let mut engine = engine(&path, (w, h), 20.0);
        let camera = engine.camera(
            DVec3::new(960.0, 600.0, 1900.0),
            DVec3::new(960.0, 200.0, 900.0),
            false,
        );
        let precisions: &[Precision] = if w * h > 1 << 20 {
            &[Precision::Fixed] // one frame of the big one keeps the test cheap
        } else {
            &[Precision::Fixed, Precision::Float]
        };
        for &precision in precisions {
            engine.render_settings_mut().precision = precision;
            let mut fb = Framebuffer::new(w, h, ColorFormat::Rgb565, DepthFormat::D16).unwrap();
            let report = engine.render(&camera, &mut fb).unwrap();
            check_report(&report);
            // The view looks down at the terrain: the bottom centre pixel is ground, and so is
            // at least half the screen (but for a 9 x 1 strip, which spans 158° across, most of
            // it past the terrain's sides).
            assert_ne!(
                fb.pixel(w / 2, h - 1),
                RenderSettings::default().sky,
                "{w}x{h} {precision:?}"
            );
            if w > 1 && h > 1 {
                assert!(
                    report.draw.fragments >= u64::from(w * h) / 2,
                    "{w}x{h}: {:?}",
                    report.draw
                );
            }
        }
    }
}

/// Depth resolution. A tile holds, seen from the south, a low step (the near face) in front of
/// a trench and a tall far ridge: every ray through the near face meets the far ridge
/// `SEPARATION` metres or more behind it, and strip order draws the far ridge first. A depth
/// buffer that cannot tell the two apart rejects near-face fragments (LESS fails on a tie), so
/// the fragments written fall below those of a buffer that can.
///
/// Stored depth is `f/(f-n) (1 - n/d)` quantised to a step `q`; two surfaces `Δ` apart at
/// distance `d` differ by about `Δ n / d²`, so the format resolves them while
/// `d < sqrt(Δ n / q)`: with `n` = 0.5 m (the engine's near plane 2 m above the ground) and Δ = 7 m, about
/// 480 m for 16 bits (`q = 2^-16`, either pipeline) and 122 km for the fixed pipeline's 32 bits
/// (0.32 fixed point, `q = 2^-32`). The f32 pipeline's 32-bit buffer resolves better than an
/// f32 near 1 (`q = 2^-24`, 7.7 km) would: it is measured to hold at every distance here (30 km).
#[test]
fn depth_order_holds_where_the_format_resolves_it_and_the_limits_are_where_computed() {
    const SEPARATION: f64 = 7.0;
    const NEAR: f64 = 0.5;
    let dir = tempfile::tempdir().unwrap();
    let path = archive(
        dir.path(),
        "walls",
        (17, 17),
        17,
        1.0,
        0.0625,
        |_, j| match j {
            0..=3 => 30.0,   // the far ridge's top
            4..=11 => -50.0, // the trench (rows 4..=11; the far ridge's face is rows 3..4)
            12 => 6.0,       // the near step's top
            _ => 0.0,        // the foreground (rows 13..): the near face is rows 12..13
        },
    );
    let engine = engine(&path, (64, 64), 0.5);
    let resolves = |d: f64, q: f64| SEPARATION * NEAR / (d * d) > 4.0 * q;
    let lost = |d: f64, q: f64| SEPARATION * NEAR / (d * d) < q / 4.0;
    let limit = |q: f64| (SEPARATION * NEAR / q).sqrt();
    println!(
        "depth resolves {SEPARATION} m up to {:.0} m (D16), {:.0} m (D32, fixed)",
        limit(2f64.powi(-16)),
        limit(2f64.powi(-32))
    );
    let fragments = |d: f64, precision, depth| {
        // Telephoto: the near face keeps about the same size on screen at every distance.
        let eye = DVec3::new(8.0, 3.0, 13.0 + d);
        let camera = Camera::looking_at(eye, DVec3::new(8.0, 3.0, 0.0));
        let viewport = Viewport::new(64, 64).with_fov_y(2.0 * (12.0 / d).atan());
        let view = View::new(camera, viewport, NEAR, 2.0 * d + 100.0);
        draw_as_is(&engine, &view, precision, depth).1.fragments
    };
    // (pipeline, format, the step its resolution limit is computed from).
    let cases = [
        (Precision::Fixed, DepthFormat::D16, 2f64.powi(-16)),
        (Precision::Float, DepthFormat::D16, 2f64.powi(-16)),
        (Precision::Float, DepthFormat::D32, 2f64.powi(-32)),
    ];
    for d in [20.0, 100.0, 2_000.0, 30_000.0] {
        // The fixed 32-bit buffer resolves every distance here: it is the truth.
        assert!(resolves(d, 2f64.powi(-32)));
        let truth = fragments(d, Precision::Fixed, DepthFormat::D32);
        assert!(truth > 500, "the near face shows at {d} m: {truth}");
        for (precision, depth, q) in cases {
            let got = fragments(d, precision, depth);
            if resolves(d, q) {
                assert_eq!(got, truth, "{precision:?} {depth:?} resolves {d} m");
            } else if lost(d, q) {
                assert!(
                    got + 300 < truth,
                    "{precision:?} {depth:?} cannot resolve {d} m, yet wrote {got} of {truth}"
                );
            }
        }
    }
}
