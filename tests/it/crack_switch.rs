//! Switching the crack mode between frames (`Engine::set_cracks`, the viewer's K key), or the
//! lighting (the render settings, whose vertex lighting the resident tiles hold only while it
//! is drawn): the next frame is byte for byte the frame of an engine started so, and the
//! pager's accounting stays exact (what it counts is what the tiles hold, never over the
//! limit), also when the new mode does not fit the limit and when tiles are still in flight.

use crate::support::crack_scene;

use crack_scene::scene;
use glam::DVec3;
use stripmask::Viewport;
use stripmask::db::source;
use stripmask::db::tile::{PartialGrid, progressive_levels};
use stripmask::engine::cracks::CrackMode;
use stripmask::engine::paging::{FAR_SHARE, PagerMode};
use stripmask::engine::render::RenderSettings;
use stripmask::engine::resident::predicted_bytes;
use stripmask::engine::{Engine, index_allowance};
use stripmask::sim::crack_metric::{CrackScene, TILE_SIZE};
use stripmask_raster::{ColorFormat, DepthFormat, Framebuffer};

const SIZE: (u32, u32) = (160, 120);

fn frame() -> Framebuffer {
    Framebuffer::new(SIZE.0, SIZE.1, ColorFormat::Rgb565, DepthFormat::D16).unwrap()
}

fn render(engine: &mut Engine, view: usize) -> Vec<u8> {
    let mut fb = frame();
    scene().render(engine, view, &mut fb).unwrap();
    fb.to_rgba_image().into_raw()
}

/// The pager counts exactly the bytes its tiles and its top hold (no fetch in flight) and the
/// index pages' allowance, within the limit, and every tile holds the vertices of `mode`.
fn assert_exact_accounting(engine: &Engine, mode: CrackMode) {
    let pager = engine.pager();
    let stats = pager.stats();
    assert_eq!(stats.fetching, 0, "{mode:?}: nothing in flight");
    let held: usize = pager.tiles().map(|(_, t)| t.bytes()).sum();
    let mut top = 0;
    for (id, tile) in pager.top() {
        assert_eq!(
            tile.vertices.len(),
            TILE_SIZE * TILE_SIZE + mode.extra_vertices(TILE_SIZE),
            "{mode:?}: top {id}"
        );
        top += tile.bytes();
    }
    assert!(stats.top_tiles > 0, "{mode:?}: the top is resident");
    assert_eq!(stats.top_bytes, top, "{mode:?}: the top's bytes");
    assert_eq!(
        stats.memory_bytes,
        held + top + stats.index_bytes,
        "{mode:?}: accounted = held"
    );
    assert!(stats.memory_bytes <= stats.memory_limit_bytes, "{mode:?}");
    let grid = TILE_SIZE * TILE_SIZE;
    for (id, tile) in pager.tiles() {
        assert_eq!(
            tile.vertices.len(),
            grid + mode.extra_vertices(TILE_SIZE),
            "{mode:?}: {id}"
        );
        let ring = pager.ledger().record(id).loaded.unwrap().ring;
        assert_eq!(
            Some(tile.bytes()),
            pager.ledger().record(id).loaded.map(|h| h.bytes),
            "{mode:?}: {id} at ring {ring}"
        );
    }
}

#[test]
fn every_switch_draws_what_a_fresh_engine_in_that_mode_draws() {
    let scene = scene();
    let mut switched = scene.engine(CrackMode::None, SIZE).unwrap();
    let view = 9;
    // Every mode after every other one: None -> Shadow -> Skirts -> Stitch -> None -> Skirts
    // -> Shadow -> Stitch -> Skirts -> None -> Stitch -> Shadow -> None.
    let order = [
        CrackMode::Shadow,
        CrackMode::Skirts,
        CrackMode::Stitch,
        CrackMode::None,
        CrackMode::Skirts,
        CrackMode::Shadow,
        CrackMode::Stitch,
        CrackMode::Skirts,
        CrackMode::None,
        CrackMode::Stitch,
        CrackMode::Shadow,
        CrackMode::None,
    ];
    let mut fresh_frames = std::collections::HashMap::new();
    let mut previous = render(&mut switched, view);
    for mode in order {
        switched.set_cracks(mode);
        assert_eq!(switched.settings().cracks, mode);
        assert_exact_accounting(&switched, mode);
        let picture = render(&mut switched, view);
        let fresh = fresh_frames.entry(mode).or_insert_with(|| {
            let mut engine = scene.engine(mode, SIZE).unwrap();
            render(&mut engine, view)
        });
        assert!(
            picture == *fresh,
            "{mode:?}: switched frame differs from a fresh engine"
        );
        assert!(
            picture != previous,
            "{mode:?}: the switch changed the picture"
        );
        assert_exact_accounting(&switched, mode);
        previous = picture;
    }
}

#[test]
fn a_mode_that_holds_more_than_the_limit_evicts_the_farthest_tiles() {
    for overview in [false, true] {
        mode_over_the_limit(overview);
    }
}

/// Fills the memory with the square of a view (after an overview, which fills the far field's
/// share, when `overview`), then switches to skirts.
fn mode_over_the_limit(overview: bool) {
    let scene = scene();
    let lit = CrackScene::settings(CrackMode::None)
        .render
        .lights_vertices();
    let tile_bytes =
        |mode| predicted_bytes(TILE_SIZE, 32, 0, progressive_levels(TILE_SIZE), mode, lit);
    // Room for 50 tiles without skirts, a square of 7 x 7 belts; with skirts it does not fit.
    let plain = tile_bytes(CrackMode::None);
    assert!(tile_bytes(CrackMode::Skirts) > plain);
    let mut fb = frame();
    let mut unbound = scene.engine(CrackMode::None, SIZE).unwrap();
    scene.render(&mut unbound, 9, &mut fb).unwrap();
    let top = unbound.pager().stats().top_bytes;
    // Room for the top, the index pages and 50 whole level-0 tiles beside the far field's
    // share.
    let mut settings = CrackScene::settings(CrackMode::None);
    let limit = ((top + 50 * plain) as f64 / (1.0 - FAR_SHARE)).ceil() as usize;
    settings.memory_limit_bytes = limit + index_allowance(limit);
    let source = source::open(&scene.archive.display().to_string()).unwrap();
    let mut engine = Engine::new(source, settings, Viewport::new(SIZE.0, SIZE.1)).unwrap();
    // The whole scene from above first: its cut asks for more tiles of the levels above 0 than
    // the far field's share holds, which fills it; then the view, whose square fills the rest.
    let (eye, target) = scene.views[9];
    let above = engine.camera(eye + DVec3::new(0.0, 20_000.0, 0.0), target, false);
    for _ in 0..if overview { 6 } else { 0 } {
        engine.render(&above, &mut fb).unwrap();
    }
    for _ in 0..3 {
        scene.render(&mut engine, 9, &mut fb).unwrap();
    }
    let before = engine.pager().stats();
    assert!(before.memory_bound, "the limit binds");
    let square = |engine: &Engine| {
        engine
            .pager()
            .tiles()
            .filter(|(id, _)| id.level == 0)
            .count()
    };
    assert_eq!(square(&engine), 49, "the 7 x 7 belts 50 tiles allow");
    let evictions = before.evictions;
    let center = engine.pager().current_tile().unwrap();
    let farthest = |engine: &Engine| {
        engine
            .pager()
            .tiles()
            .filter(|(id, _)| id.level == 0)
            .map(|(id, _)| stripmask::db::grid::Grid::ring(center, id))
            .max()
            .unwrap()
    };
    let reach = farthest(&engine);

    // The skirts' vertices grow every resident tile; what the limit leaves is the far field's
    // share it does not use, and less than a tile of the square's.
    let growth: usize = engine
        .pager()
        .tiles()
        .chain(engine.pager().top())
        .map(|(_, t)| {
            let side = t.side();
            CrackMode::Skirts.extra_vertices(side) * std::mem::size_of::<stripmask_raster::Vertex>()
        })
        .sum();
    let slack = before.memory_limit_bytes - before.memory_bytes;
    engine.set_cracks(CrackMode::Skirts);
    let after = engine.pager().stats();
    assert_exact_accounting(&engine, CrackMode::Skirts);
    if growth > slack {
        assert!(
            after.evictions > evictions,
            "skirts do not fit: tiles evicted"
        );
        assert!(after.loaded_tiles < before.loaded_tiles);
    } else {
        assert_eq!(after.evictions, evictions, "skirts fit: nothing evicted");
    }
    assert!(farthest(&engine) <= reach);
    assert!(
        engine.pager().get(center).is_some(),
        "the current tile stays"
    );

    // Frames go on within the limit, and back without skirts everything fits again.
    for _ in 0..3 {
        scene.render(&mut engine, 9, &mut fb).unwrap();
        assert_exact_accounting(&engine, CrackMode::Skirts);
    }
    engine.set_cracks(CrackMode::Stitch);
    assert_exact_accounting(&engine, CrackMode::Stitch);
    assert_eq!(
        engine.pager().stats().errors,
        0,
        "{:?}",
        engine.pager().last_error()
    );
}

/// Every tile holds normals and shades exactly while the surface is drawn lit.
fn assert_lit_as_drawn(engine: &Engine) {
    let lit = engine.settings().render.lights_vertices();
    let pager = engine.pager();
    for (id, tile) in pager.tiles().chain(pager.top()) {
        assert_eq!(tile.light.is_some(), lit, "{id}");
        let normals = if lit && !tile.absent {
            tile.side().pow(2)
        } else {
            0
        };
        assert_eq!(tile.normals.len(), normals, "{id}");
    }
}

#[test]
fn every_lighting_switch_draws_what_a_fresh_engine_so_lit_draws() {
    let scene = scene();
    let mode = CrackMode::Stitch;
    let mut switched = scene.engine(mode, SIZE).unwrap();
    let view = 9;
    let mut previous = render(&mut switched, view);
    assert_lit_as_drawn(&switched);
    let textured = RenderSettings::default().sampler;
    // Lit over the texture, unlit, lit without a texture, unlit again.
    for (lighting, sampler) in [
        (true, textured),
        (false, textured),
        (false, None),
        (false, textured),
    ] {
        let render_settings = switched.render_settings_mut();
        render_settings.lighting = lighting;
        render_settings.sampler = sampler;
        let picture = render(&mut switched, view);
        assert_lit_as_drawn(&switched);
        assert_exact_accounting(&switched, mode);
        let mut settings = CrackScene::settings(mode);
        settings.render.lighting = lighting;
        settings.render.sampler = sampler;
        let fresh = render(&mut scene.engine_with(settings, SIZE).unwrap(), view);
        assert!(
            picture == fresh,
            "lighting {lighting}, {sampler:?}: switched frame differs from a fresh engine"
        );
        assert!(picture != previous, "lighting {lighting}, {sampler:?}");
        previous = picture;
    }
}

#[test]
fn tiles_in_flight_during_a_switch_arrive_in_the_new_mode() {
    switch_in_flight(|engine| engine.set_cracks(CrackMode::Skirts));
    switch_in_flight(|engine| engine.render_settings_mut().lighting = true);
}

/// Switches with fetches in flight, and checks the tiles once they all arrived.
fn switch_in_flight(switch: impl Fn(&mut Engine)) {
    let scene = scene();
    let mut settings = CrackScene::settings(CrackMode::None);
    settings.pager_mode = PagerMode::Simulated { queue_depth: 8 };
    let source = source::open(&scene.archive.display().to_string()).unwrap();
    let mut engine = Engine::new(source, settings, Viewport::new(SIZE.0, SIZE.1)).unwrap();
    let mut fb = frame();
    // The first frame fetches the top, the second the tiles.
    scene.render(&mut engine, 9, &mut fb).unwrap();
    scene.render(&mut engine, 9, &mut fb).unwrap();
    assert!(engine.pager().stats().fetching > 0, "fetches in flight");
    switch(&mut engine);
    let mut frames = 0;
    while engine.pager().stats().fetching > 0 || frames < 2 {
        engine.set_time(f64::from(frames));
        scene.render(&mut engine, 9, &mut fb).unwrap();
        frames += 1;
        assert!(frames < 200, "the pager settles");
    }
    assert_exact_accounting(&engine, engine.settings().cracks);
    assert_lit_as_drawn(&engine);
    assert_eq!(
        engine.pager().stats().errors,
        0,
        "{:?}",
        engine.pager().last_error()
    );
}
