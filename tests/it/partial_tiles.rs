//! Partial tiles (only their first progressive levels held) draw exactly what the whole tile
//! draws at the matching mask level with the same texture mips, and stitch without cracks
//! against neighbours holding other level counts.

use glam::DVec3;
use stripmask::db::grid::TileId;
use stripmask::db::tile::Tile;
use stripmask::engine::budget::drawable_level;
use stripmask::engine::camera::{Camera, View};
use stripmask::engine::cracks::neighbours::{Neighbourhood, neighbour_levels};
use stripmask::engine::cracks::{CrackMode, TileIndices};
use stripmask::engine::masks::{LevelSet, MaskSet};
use stripmask::engine::partial_meshes::PartialMeshes;
use stripmask::engine::render::{RenderSettings, TileDraw, TileMeshes, draw_tiles};
use stripmask::engine::resident::ResidentTile;
use stripmask::engine::shading::Light;
use stripmask::engine::terrain::TerrainFrame;
use stripmask::engine::viewport::Viewport;
use stripmask::sim::crack_metric::BACKGROUND;
use stripmask_raster::{ColorFormat, DepthFormat, Framebuffer, RasterTarget, Rasterizer};

/// Samples per tile side: 5 progressive levels, mask levels 0 ..= 15.
const S: usize = 17;
const TEXTURE: usize = 16;
const TILES: u32 = 3;
const SPACING: f64 = 10.0;
const QUANTUM: f32 = 0.125;

/// Rough relief by global sample, so that coarse levels miss a lot and borders are shared.
fn height(gi: usize, gj: usize) -> f32 {
    let (x, z) = (gi as f32, gj as f32);
    60.0 + 25.0 * (0.9 * x).sin() * (0.7 * z).cos() + 10.0 * (0.31 * (x + z)).sin()
}

/// Tile `(tx, ty)` of the 3 x 3 terrain, whole.
fn tile(tx: usize, ty: usize) -> Tile {
    let heights: Vec<f32> = (0..S * S)
        .map(|k| height(tx * (S - 1) + k % S, ty * (S - 1) + k / S))
        .collect();
    let texture: Vec<[u8; 3]> = (0..TEXTURE * TEXTURE)
        .map(|k| {
            let (x, y) = (tx * TEXTURE + k % TEXTURE, ty * TEXTURE + k / TEXTURE);
            [60 + (x * 37 % 120) as u8, 100 + (y * 23 % 100) as u8, 40]
        })
        .collect();
    Tile::new(&heights, S, QUANTUM, &texture, TEXTURE).unwrap()
}

fn terrain() -> TerrainFrame {
    TerrainFrame {
        tiles_x: TILES,
        tiles_y: TILES,
        tile_size: S,
        spacing: SPACING,
        quantum: f64::from(QUANTUM),
        heights: (0.0, 120.0),
        origin: DVec3::ZERO,
        source_samples: (TILES * (S as u32 - 1) + 1, TILES * (S as u32 - 1) + 1),
        archive_origin: (0.0, 0.0),
    }
}

/// Nearly straight down over the middle tile: the terrain fills the whole view, so every
/// background pixel is a crack.
fn view() -> View {
    let camera = Camera::looking_at(
        DVec3::new(240.0, 300.0, 240.0),
        DVec3::new(240.0, 0.0, 228.0),
    );
    View::new(camera, Viewport::new(96, 72), 1.0, 1000.0)
}

/// Draws `tiles[ty * 3 + tx]` at whole-tile mask levels `levels` (same order) in `mode`.
fn draw(
    tiles: &[ResidentTile],
    levels: &[usize],
    mode: CrackMode,
    settings: &RenderSettings,
) -> Framebuffer {
    let terrain = terrain();
    let view = view();
    let ids: Vec<(TileId, usize)> = (0..tiles.len())
        .map(|k| (TileId::new(k as u32 % TILES, k as u32 / TILES), levels[k]))
        .collect();
    let places: Vec<TileId> = ids.iter().map(|&(id, _)| id).collect();
    let around = neighbour_levels(&Neighbourhood::of(&places), levels, S);
    let mut draws: Vec<TileDraw<'_>> = ids
        .iter()
        .zip(around)
        .zip(tiles)
        .map(|((&(id, level), neighbours), tile)| {
            let (lo, hi) = terrain.tile_box(id, f64::from(tile.min), f64::from(tile.max));
            TileDraw {
                id,
                tile,
                level,
                neighbours,
                distance: ((lo + hi) / 2.0 - view.camera.position).length(),
            }
        })
        .collect();
    let masks = MaskSet::new(S, LevelSet::All);
    let mut cracks = TileIndices::new(mode, S);
    let mut held = PartialMeshes::new();
    let mut fb = Framebuffer::new(96, 72, ColorFormat::Rgba8888, DepthFormat::D32).unwrap();
    draw_tiles(
        &mut RasterTarget::new(&mut fb, &mut Rasterizer::with_threads(1)),
        &view,
        &terrain,
        &mut draws,
        TileMeshes {
            masks: &masks,
            cracks: &mut cracks,
            partial: Some(&mut held),
            morph: None,
        },
        settings,
    )
    .unwrap();
    fb
}

fn resident(tile: &Tile, texture_base: usize, mode: CrackMode) -> ResidentTile {
    ResidentTile::new(tile, texture_base, SPACING, Some(&Light::default()), mode)
}

fn crack_pixels(fb: &Framebuffer) -> usize {
    (0..fb.height())
        .flat_map(|y| (0..fb.width()).map(move |x| (x, y)))
        .filter(|&(x, y)| fb.pixel(x, y) == BACKGROUND)
        .count()
}

/// Lit and textured, without fog: a tile drawn at a mask level is lit from the grid that level
/// needs whether it is whole or partial, so everything must match, vertex colours included.
fn lit() -> RenderSettings {
    RenderSettings {
        fog: false,
        sky: BACKGROUND,
        ..RenderSettings::default()
    }
}

#[test]
fn a_tile_holding_k_levels_draws_exactly_the_whole_tile_at_the_matching_mask_level() {
    let whole: Vec<Tile> = (0..9).map(|k| tile(k % 3, k / 3)).collect();
    for held in 1..=5 {
        // Stride 2^(5 - held): the mask keeping every stride-th sample.
        let level = (1 << (5 - held)) - 1;
        for mode in CrackMode::ALL {
            let partial: Vec<ResidentTile> = whole
                .iter()
                .map(|t| resident(&t.truncated(held), 0, mode))
                .collect();
            // A whole tile holding the same texture mips: the partial tile lacks the finer
            // ones, which the whole tile's triangles would otherwise read where their size on
            // screen asks for them.
            let first_mip = whole[0].truncated(held).first_mip;
            let texture_base = first_mip;
            let full: Vec<ResidentTile> = whole
                .iter()
                .map(|t| resident(t, texture_base, mode))
                .collect();
            let a = draw(&partial, &[level; 9], mode, &lit());
            let b = draw(&full, &[level; 9], mode, &lit());
            assert!(
                a.to_rgba_image() == b.to_rgba_image(),
                "{held} levels at mask level {level}, {mode:?}, whole texture from mip \
                 {texture_base}"
            );
            assert!(
                crack_pixels(&a) < (96 * 72) / 2,
                "the terrain fills the view"
            );
        }
    }
}

#[test]
fn stitched_tiles_holding_different_level_counts_leave_no_crack() {
    // Levels held per tile (row-major) and the mask level each asks for before snapping.
    let held = [5, 2, 4, 3, 1, 5, 5, 3, 2];
    let asked = [0, 0, 1, 0, 0, 2, 7, 3, 0];
    let levels: Vec<usize> = (0..9)
        .map(|k| {
            let stride = 1 << (5 - held[k]);
            drawable_level(asked[k], stride - 1, true)
        })
        .collect();
    let lit = lit();
    let tiles = |mode| -> Vec<ResidentTile> {
        (0..9)
            .map(|k| resident(&tile(k % 3, k / 3).truncated(held[k]), 0, mode))
            .collect()
    };
    let open = crack_pixels(&draw(
        &tiles(CrackMode::None),
        &levels,
        CrackMode::None,
        &lit,
    ));
    assert!(
        open > 0,
        "the view crosses borders between levels: {levels:?}"
    );
    let stitched = draw(&tiles(CrackMode::Stitch), &levels, CrackMode::Stitch, &lit);
    assert_eq!(
        crack_pixels(&stitched),
        0,
        "{levels:?}, {open} without stitching"
    );
}
