//! The CPU cost of one frame's bookkeeping: frustum culling of the tiles' boxes, visual
//! importance (Algorithm 2), the budget controller's update, the budget's share with its mask
//! choice per tile (by importance or by projected error), and the look-up of each chosen mask's
//! index buffer.
//!
//! `cargo bench --bench frame`. Scenes: 1,000 tiles all in view (a 40 x 25 grid seen from high
//! above), and a 32 x 32 grid seen from its southern edge, where about half the tiles are culled;
//! each with either allocation. Tiles have 65 x 65 samples. To compare with a frame: 5 % of a
//! 7 fps frame is 7.1 ms, of a 25 fps frame 2 ms.
//!
//! Then the cut through the pyramid (`engine::cut`) of one view — 1,500 m above the north-west
//! corner, looking 20 km ahead, τ = 1 px — over models of 16², 256², 4,096² and 16,384² tiles
//! with every tile of every level resident: what the walk costs as the model grows.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use glam::dcamera::rh::{proj::directx::perspective, view::look_at_mat4};
use glam::{DMat4, DVec3};
use stripmask::db::archive::{Codec, Header};
use stripmask::db::grid::TileId;
use stripmask::db::tile::Tile;
use stripmask::engine::allocation::{Allocation, TileErrors};
use stripmask::engine::budget::{BudgetController, BudgetSettings};
use stripmask::engine::camera::{Camera, View};
use stripmask::engine::cracks::CrackMode;
use stripmask::engine::cut::{CutSettings, Holdings, LastFrame, cut};
use stripmask::engine::frustum::{Aabb, Frustum};
use stripmask::engine::importance::{TileMeasure, Weights, visual_importance};
use stripmask::engine::masks::{LevelSet, MaskSet};
use stripmask::engine::resident::ResidentTile;
use stripmask::engine::shading::Light;
use stripmask::engine::terrain::TerrainFrame;
use stripmask::engine::viewport::Viewport;

/// Tile side in metres: 64 cells of 10 m.
const TILE: f64 = 640.0;

/// Pixels per metre at one metre: the focal length of a 240-pixel-tall 60° view.
const FOCAL_PX: f64 = 207.8;

struct Scene {
    boxes: Vec<Aabb>,
    relief: Vec<f64>,
    /// Per tile, its levels' errors, metres: growing with the level up to a third of its relief.
    level_errors: Vec<Vec<f32>>,
    eye: DVec3,
    view_projection: DMat4,
}

impl Scene {
    /// A `columns x rows` grid of tiles with pseudo-random elevations and reliefs.
    fn grid(
        columns: usize,
        rows: usize,
        eye: DVec3,
        target: DVec3,
        up: DVec3,
        aspect: f64,
    ) -> Self {
        let mut boxes = vec![];
        let mut relief = vec![];
        for j in 0..rows {
            for i in 0..columns {
                let k = (i * 7919 + j * 104_729) % 1000;
                let low = k as f64 * 0.3;
                let high = low + 20.0 + (k % 97) as f64 * 4.0;
                let min = DVec3::new(i as f64 * TILE, low, j as f64 * TILE);
                boxes.push(Aabb::new(min, DVec3::new(min.x + TILE, high, min.z + TILE)));
                relief.push(high - low);
            }
        }
        let level_errors = relief
            .iter()
            .map(|&r| {
                (0..64)
                    .map(|l| (r / 3.0 * l as f64 / 63.0) as f32)
                    .collect()
            })
            .collect();
        Self {
            boxes,
            relief,
            level_errors,
            eye,
            view_projection: perspective(60f64.to_radians(), aspect, 1.0, 100_000.0)
                * look_at_mat4(eye, target, up),
        }
    }
}

/// Reused buffers of the frame loop.
#[derive(Default)]
struct Frame {
    visible: Vec<usize>,
    measures: Vec<TileMeasure>,
    finest: Vec<usize>,
}

/// One frame's bookkeeping; returns the triangles to draw and the index count of their masks.
fn bookkeeping(
    scene: &Scene,
    frame: &mut Frame,
    masks: &MaskSet,
    controller: &mut BudgetController,
    last_frame: (f64, usize),
    rule: Allocation,
) -> (usize, usize) {
    let frustum = Frustum::from_view_projection(&scene.view_projection);
    frame.visible.clear();
    frame.measures.clear();
    for (tile, aabb) in scene.boxes.iter().enumerate() {
        if frustum.intersects(aabb) {
            frame.visible.push(tile);
            frame.measures.push(TileMeasure {
                distance: aabb.distance(scene.eye),
                height: scene.relief[tile],
            });
        }
    }
    let importance = visual_importance(&frame.measures, Weights::default());
    let budget = controller.record(last_frame.0, last_frame.1);
    let errors: Vec<TileErrors<'_>> = frame
        .visible
        .iter()
        .zip(&frame.measures)
        .map(|(&tile, m)| TileErrors {
            metres: &scene.level_errors[tile],
            pixels_per_metre: FOCAL_PX / m.distance.max(20.0),
            kept: None,
        })
        .collect();
    frame.finest.clear();
    frame.finest.resize(frame.visible.len(), 0);
    let allocation = rule.share(budget, &importance, masks, &errors, &frame.finest);
    let triangles = allocation.iter().map(|a| a.triangles).sum();
    let indices = allocation
        .iter()
        .map(|a| masks.indices(a.level).len())
        .sum();
    (triangles, indices)
}

fn bench_scene(c: &mut Criterion, name: &str, scene: &Scene, rule: Allocation) {
    let masks = MaskSet::new(65, LevelSet::All);
    let mut controller = BudgetController::new(BudgetSettings::default());
    let mut frame = Frame::default();
    let budget = controller.budget();
    let last = (0.04, budget);
    let (triangles, _) = bookkeeping(scene, &mut frame, &masks, &mut controller, last, rule);
    println!(
        "{name}: {} of {} tiles visible, {triangles} triangles of a {budget} budget",
        frame.visible.len(),
        scene.boxes.len()
    );
    c.bench_function(name, |b| {
        b.iter(|| {
            // A frame that met the target with the whole budget: the budget stays put.
            let last = (0.04, controller.budget());
            black_box(bookkeeping(
                black_box(scene),
                &mut frame,
                &masks,
                &mut controller,
                last,
                rule,
            ))
        })
    });
}

fn frames(c: &mut Criterion) {
    // 40 x 25 tiles (25.6 x 16 km) seen straight down from 16 km: all 1,000 in view.
    let center = DVec3::new(20.0 * TILE, 0.0, 12.5 * TILE);
    let overview = Scene::grid(
        40,
        25,
        center + DVec3::new(0.0, 16_000.0, 0.0),
        center,
        DVec3::NEG_Z,
        1.6,
    );
    assert_eq!(
        overview
            .boxes
            .iter()
            .filter(|b| Frustum::from_view_projection(&overview.view_projection).intersects(b))
            .count(),
        1_000
    );
    bench_scene(
        c,
        "bookkeeping_1000_visible_tiles",
        &overview,
        Allocation::Importance,
    );
    bench_scene(
        c,
        "bookkeeping_1000_visible_tiles_by_error",
        &overview,
        Allocation::Error,
    );

    // 32 x 32 tiles seen from 500 m above the middle of the southern edge, looking north
    // through a 3:4 portrait view: 488 tiles in view.
    let eye = DVec3::new(16.0 * TILE, 500.0, 32.0 * TILE);
    let edge = Scene::grid(
        32,
        32,
        eye,
        eye + DVec3::new(0.0, -100.0, -1000.0),
        DVec3::Y,
        0.75,
    );
    let in_view = edge
        .boxes
        .iter()
        .filter(|b| Frustum::from_view_projection(&edge.view_projection).intersects(b))
        .count();
    assert!((400..=600).contains(&in_view), "{in_view}");
    bench_scene(
        c,
        "bookkeeping_32x32_grid_about_half_culled",
        &edge,
        Allocation::Importance,
    );
    bench_scene(
        c,
        "bookkeeping_32x32_grid_about_half_culled_by_error",
        &edge,
        Allocation::Error,
    );
}

/// Every tile of every level resident: one shared copy per level, whose finest error (against
/// the full resolution) doubles with the level.
struct EveryTile {
    per_level: Vec<ResidentTile>,
}

impl Holdings for EveryTile {
    fn tile(&self, id: TileId) -> Option<&ResidentTile> {
        self.per_level.get(usize::from(id.level))
    }

    fn covered(&self, _: TileId) -> u32 {
        1
    }
}

fn cuts(c: &mut Criterion) {
    const S: usize = 65;
    let heights: Vec<f32> = (0..S * S)
        .map(|k| 300.0 + 80.0 * ((k % S) as f32 * 0.2).sin() * ((k / S) as f32 * 0.15).cos())
        .collect();
    let tile = Tile::new(&heights, S, 0.0625, &[[90, 120, 80]; 64 * 64], 64).unwrap();
    for side in [16u32, 256, 4096, 16384] {
        let header = Header {
            tiles_x: side,
            tiles_y: side,
            tile_size: S as u32,
            texture_size: 64,
            codec: Codec::Lz4,
            source_width: side * 64 + 1,
            source_height: side * 64 + 1,
            spacing: 40.0,
            vertical_scale: 1.0,
            origin_x: 0.0,
            origin_y: 0.0,
            min_height: 220.0,
            max_height: 380.0,
            height_quantum: 0.0625,
            nodata_filled: 0,
            nodata_flattened: 0,
            absent_tiles: 0,
            top_level: 0,
            top_offset: 0,
            top_len: 0,
            archive_len: 0,
            georef: None,
        };
        let terrain = TerrainFrame::new(&header);
        let pyramid = header.pyramid();
        let held = EveryTile {
            per_level: (0..pyramid.levels() as u8)
                .map(|level| {
                    let mut copy = ResidentTile::of_level(
                        &tile,
                        level,
                        0,
                        40.0,
                        Some(&Light::default()),
                        CrackMode::Stitch,
                    );
                    copy.level_errors[0] = 4.0 * f32::powi(2.0, i32::from(level));
                    copy
                })
                .collect(),
        };
        let camera = Camera::looking_at(
            DVec3::new(3000.0, 1800.0, 3000.0),
            DVec3::new(23_000.0, 0.0, 23_000.0),
        );
        let view = View::new(camera, Viewport::new(320, 240), 1.0, 1e7);
        let settings = CutSettings {
            max_error_px: Some(1.0),
            water_px: None,
            clearance: 1.0,
        };
        let last = LastFrame::default();
        let drawn = || {
            cut(&held, &terrain, &pyramid, &view, &settings, &last)
                .tiles
                .len()
        };
        println!("cut over {side}² tiles: {} drawn", drawn());
        c.bench_function(&format!("cut_over_{side}x{side}_tiles"), |b| {
            b.iter(|| black_box(drawn()))
        });
    }
}

criterion_group!(benches, frames, cuts);
criterion_main!(benches);
