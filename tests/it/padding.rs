//! A model whose size is not `2^n k + 1` samples is padded east and south to whole tiles; the
//! padding is never drawn: the terrain ends exactly at the model's last samples, seen straight
//! down across its east and its south edge; and the minimap shows the model's extent only.

use glam::DVec3;
use stripmask::Viewport;
use stripmask::db::builder::{BuildOptions, build};
use stripmask::db::dem::{MemoryReader, NodataFill};
use stripmask::db::source;
use stripmask::engine::paging::PagerMode;
use stripmask::engine::{Engine, EngineSettings, FrameTiming};
use stripmask::sim::hud::hud_info;
use stripmask_platform::{Hud, MinimapCell, compose_rgba};
use stripmask_raster::{ColorFormat, DepthBuffer, DepthFormat, Framebuffer};

/// 150 x 100 samples 30 m apart in tiles of 33: 5 x 4 tiles of 161 x 129 samples, so 11
/// columns and 29 rows of padding.
const SIZE: (usize, usize) = (150, 100);
const SPACING: f64 = 30.0;
const W: u32 = 160;
const H: u32 = 120;

/// Whether each pixel of the frame from `eye` towards `target` drew terrain, once every tile
/// is loaded.
fn drawn(engine: &mut Engine, eye: DVec3, target: DVec3) -> Vec<bool> {
    let mut fb = Framebuffer::new(W, H, ColorFormat::Rgb565, DepthFormat::D16).unwrap();
    for _ in 0..40 {
        let camera = engine.camera(eye, target, false);
        engine.render(&camera, &mut fb).unwrap();
    }
    let DepthBuffer::D16(depth) = fb.depth() else {
        unreachable!("a 16-bit depth buffer")
    };
    depth.iter().map(|&d| d != u16::MAX).collect()
}

/// Builds a model of `n x m` samples in tiles of 33 and opens an engine on it that loads every
/// tile at once.
fn odd_model(dir: &std::path::Path, (n, m): (usize, usize)) -> Engine {
    let samples = (0..n * m)
        .map(|k| {
            let (i, j) = ((k % n) as f32, (k / n) as f32);
            100.0 + 20.0 * (i * 0.11).sin() * (j * 0.07).cos()
        })
        .collect();
    let reader = MemoryReader::new("odd", n, m, samples).unwrap();
    let path = dir.join("odd.smdb");
    let options = BuildOptions {
        tile_size: 33,
        spacing: Some(SPACING),
        texture_factor: 1,
        ..BuildOptions::default()
    };
    build(NodataFill::new(reader, None), &path, &options, &|_, _| {}).unwrap();
    let settings = EngineSettings {
        memory_limit_bytes: 64 << 20,
        pager_mode: PagerMode::Stepped {
            fetches_per_update: 64,
        },
        threads: 1,
        frame_timing: FrameTiming::Told,
        ..EngineSettings::default()
    };
    Engine::new(
        source::open(path.to_str().unwrap()).unwrap(),
        settings,
        Viewport::new(W, H),
    )
    .unwrap()
}

#[test]
fn padding_is_never_drawn_and_the_terrain_ends_at_the_models_last_samples() {
    let dir = tempfile::tempdir().unwrap();
    let mut engine = odd_model(dir.path(), SIZE);
    let (east, south) = engine.terrain().source_extent();
    assert_eq!((east, south), (149.0 * SPACING, 99.0 * SPACING));
    assert!(engine.terrain().extent().0 > east && engine.terrain().extent().1 > south);
    // Straight down (tilted a little along the edge) from 600 m above the edge: the vertical
    // plane through the edge holds the eye and the view direction, so the edge is the
    // middle column, whatever the heights; one half of the frame is the model, the other
    // half the padding and beyond.
    let views = [
        (
            DVec3::new(east, 700.0, 0.5 * south),
            DVec3::new(0.0, -600.0, 60.0),
        ),
        (
            DVec3::new(0.4 * east, 700.0, south),
            DVec3::new(60.0, -600.0, 0.0),
        ),
    ];
    for (eye, look) in views {
        let px = drawn(&mut engine, eye, eye + look);
        let column = |x: u32| (0..H).map(|y| px[(y * W + x) as usize]).collect::<Vec<_>>();
        let full = |x| column(x).iter().all(|&d| d);
        let empty = |x| column(x).iter().all(|&d| !d);
        // Which half is the model depends on the camera's handedness.
        let (model, padding): (Vec<u32>, Vec<u32>) = if full(0) {
            ((0..W / 2 - 2).collect(), (W / 2 + 2..W).collect())
        } else {
            ((W / 2 + 2..W).collect(), (0..W / 2 - 2).collect())
        };
        for x in model {
            assert!(full(x), "{eye}: column {x} of the model is not all terrain");
        }
        for x in padding {
            assert!(empty(x), "{eye}: column {x}, on the padding, drew terrain");
        }
    }
}

#[test]
fn the_minimap_shows_the_models_extent_and_no_padding() {
    // 300 x 200 samples in tiles of 33: 10 x 7 tiles, the model ends 9.34 tiles east and
    // 6.22 tiles south of the north-west corner.
    let dir = tempfile::tempdir().unwrap();
    let mut engine = odd_model(dir.path(), (300, 200));
    let (east, south) = engine.terrain().source_extent();
    let tile = engine.terrain().tile_metres();
    let (ex, ey) = (east / tile, south / tile);
    assert_eq!(
        (engine.terrain().tiles_x, engine.terrain().tiles_y),
        (10, 7)
    );
    // Near the north-west corner looking south-east, so the viewer's arrow is far from the
    // padding.
    let mut fb = Framebuffer::new(W, H, ColorFormat::Rgb565, DepthFormat::D16).unwrap();
    let eye = DVec3::new(100.0, 900.0, 100.0);
    let camera = engine.camera(eye, eye + DVec3::new(500.0, -300.0, 500.0), false);
    let mut report = engine.render(&camera, &mut fb).unwrap();
    for _ in 0..10 {
        report = engine.render(&camera, &mut fb).unwrap();
    }
    let info = hud_info(&engine, &report, 30.0);
    let map = info.minimap.as_ref().unwrap();
    assert_eq!((map.width, map.height), (10, 7));
    let (vx, vy) = map.viewer;
    assert!(
        (f64::from(vx) - 100.0 / tile).abs() < 1e-4 && (f64::from(vy) - 100.0 / tile).abs() < 1e-4
    );

    let (w, h) = (640, 480);
    let mut hud = Hud::new(true);
    let overlay = hud.render(&info, w, h).unwrap();
    let under = Framebuffer::new(w, h, ColorFormat::Rgba8888, DepthFormat::None).unwrap();
    let shown = compose_rgba(&under, Some(overlay));
    let origin = overlay.minimap_cell(0, 0).unwrap();
    let pitch = overlay.minimap_cell(1, 0).unwrap().x - origin.x;
    assert!(
        pitch >= 8,
        "cells of {pitch} px are too small for this test"
    );
    let states: Vec<[u8; 3]> = [
        MinimapCell::Empty,
        MinimapCell::Cached,
        MinimapCell::Loaded,
        MinimapCell::Fetching,
        MinimapCell::Rendered,
    ]
    .iter()
    .map(|c| c.color())
    .collect();
    // Every pixel in a cell's colour shows only the model: its far edge, in tile units from
    // the map's corner, is within the model's extent.
    let (mut last_column, mut last_row) = (0, 0);
    for (x, y, px) in shown.enumerate_pixels() {
        if !states.contains(&[px[0], px[1], px[2]]) || x < origin.x || y < origin.y {
            continue;
        }
        let reach = |p: u32, o: u32| f64::from(p + 1 - o) / f64::from(pitch);
        assert!(
            reach(x, origin.x) <= ex && reach(y, origin.y) <= ey,
            "minimap pixel ({x}, {y}) shows padding: it reaches {:.3} x {:.3} tiles of a \
             {ex:.3} x {ey:.3} tile model",
            reach(x, origin.x),
            reach(y, origin.y)
        );
        last_column = last_column.max((x - origin.x) / pitch);
        last_row = last_row.max((y - origin.y) / pitch);
    }
    // The edge tiles, part model and part padding, are drawn cut at the extent.
    assert_eq!((last_column, last_row), (9, 6));
    let cut = overlay.minimap_cell(9, 6).unwrap();
    assert!(cut.width < pitch - 1 && cut.height < pitch - 1, "{cut:?}");
}
