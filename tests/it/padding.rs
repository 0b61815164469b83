//! A model whose size is not `2^n k + 1` samples is padded east and south to whole tiles; the
//! padding is never drawn: the terrain ends exactly at the model's last samples, seen straight
//! down across its east and its south edge.

use glam::DVec3;
use stripmask::db::builder::{BuildOptions, build};
use stripmask::db::dem::{MemoryReader, NodataFill};
use stripmask::db::source;
use stripmask::engine::paging::PagerMode;
use stripmask::engine::{Engine, EngineSettings};
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

#[test]
fn padding_is_never_drawn_and_the_terrain_ends_at_the_models_last_samples() {
    let dir = tempfile::tempdir().unwrap();
    let (n, m) = SIZE;
    let samples = (0..n * m)
        .map(|k| {
            let (i, j) = ((k % n) as f32, (k / n) as f32);
            100.0 + 20.0 * (i * 0.11).sin() * (j * 0.07).cos()
        })
        .collect();
    let reader = MemoryReader::new("odd", n, m, samples).unwrap();
    let path = dir.path().join("odd.smdb");
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
        ..EngineSettings::default()
    };
    let mut engine =
        Engine::new(source::open(path.to_str().unwrap()).unwrap(), settings, H).unwrap();
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
