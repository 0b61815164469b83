//! Progressive streaming end to end on a synthetic archive: the memory limit holds through a
//! flight, every tile the view needs ends up at the level it needs, settled partial tiles draw
//! exactly what whole tiles draw, and over a slow link the first picture comes sooner for far
//! fewer bytes.

use std::time::Duration;

use glam::DVec3;
use stripmask::Viewport;
use stripmask::db::archive::ArchiveReader;
use stripmask::db::builder::BuildOptions;
use stripmask::db::grid::TileId;
use stripmask::db::source;
use stripmask::db::source::throttle::LinkProfile;
use stripmask::db::tile::PartialGrid;
use stripmask::engine::geomorph::Geomorph;
use stripmask::engine::masks::LevelSet;
use stripmask::engine::paging::PagerMode;
use stripmask::engine::paging::stream::{StreamSettings, Streaming};
use stripmask::engine::{Engine, EngineSettings, FrameReport, FrameTiming};
use stripmask::sim::clock::{Clock, CostModel, connect};
use stripmask::sim::flight::{Builtin, Flight};
use stripmask_raster::{ColorFormat, DepthFormat, Framebuffer};

use crate::support::hills;
use hills::{archive, synthetic};

fn settings(memory_limit_bytes: usize, streaming: Streaming, mode: PagerMode) -> EngineSettings {
    EngineSettings {
        memory_limit_bytes,
        pager_mode: mode,
        threads: 1,
        streaming,
        frame_timing: FrameTiming::Told,
        lift_to_clearance: true,
        ..EngineSettings::default()
    }
}

fn progressive() -> Streaming {
    Streaming::Progressive(StreamSettings::default())
}

fn open(path: &std::path::Path, settings: EngineSettings) -> Engine {
    Engine::new(
        source::open(path.to_str().unwrap()).unwrap(),
        settings,
        Viewport::new(160, 120),
    )
    .unwrap()
}

fn frame() -> Framebuffer {
    Framebuffer::new(160, 120, ColorFormat::Rgb565, DepthFormat::D16).unwrap()
}

/// Accounted bytes never pass the limit and equal what the resident tiles and the top hold and
/// what is set aside for the index pages.
fn check_memory(engine: &Engine, report: &FrameReport) {
    let stats = report.pager;
    assert!(
        stats.memory_peak_bytes <= stats.memory_limit_bytes,
        "{stats:?}"
    );
    if stats.fetching == 0 {
        let held: usize = engine.pager().tiles().map(|(_, t)| t.bytes()).sum();
        assert_eq!(
            held + stats.top_bytes + stats.index_bytes,
            stats.memory_bytes
        );
    }
}

#[test]
fn a_progressive_flight_keeps_the_limit_and_ends_with_every_tile_at_its_level() {
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path(), 33);
    // Room for about a fifth of the 64 whole tiles: fine levels must come and go.
    let limit = 600_000;
    let mode = PagerMode::Stepped {
        fetches_per_update: 3,
    };
    let mut engine = open(&path, settings(limit, progressive(), mode));
    let flight = Flight::builtin(Builtin::Low, engine.terrain());
    let mut fb = frame();
    let (mut t, mut partial_frames) = (0.0, 0);
    while t < flight.duration() {
        let (eye, target) = flight.at(t);
        let camera = engine.camera(eye, target, flight.above_ground);
        engine.set_time(t);
        let report = engine.render(&camera, &mut fb).unwrap();
        check_memory(&engine, &report);
        partial_frames += usize::from(engine.pager().tiles().any(|(_, t)| !t.is_complete()));
        t += 0.5;
    }
    assert!(partial_frames > 0, "the flight drew partial tiles");
    let stream = engine.stream_stats().unwrap().clone();
    assert!(stream.requests > 0);
    // Hold still at the end: every tile drawn reaches the level its importance buys.
    let (eye, target) = flight.at(flight.duration());
    let mut last = None;
    for k in 0..80 {
        let camera = engine.camera(eye, target, flight.above_ground);
        engine.set_time(t + f64::from(k) * 0.5);
        let report = engine.render(&camera, &mut fb).unwrap();
        check_memory(&engine, &report);
        last = Some(report);
    }
    let last = last.unwrap();
    assert!(last.rendered_tiles > 0);
    assert!(
        last.rendered.iter().all(|r| !r.capped),
        "{:?}",
        last.rendered
    );
    assert_eq!(
        engine.pager().stats().errors,
        0,
        "{:?}",
        engine.pager().last_error()
    );
}

/// The same view settled from whole tiles and from progressive tiles (lit and fogged, without
/// texture: a partial tile holds only the texture mips of its levels, where a whole tile's
/// triangles read finer ones as their size on screen asks) with `geomorph`: checks that both
/// drew the same levels, some tiles partial and at three levels or more, and returns the two
/// pictures.
fn settled_whole_and_partial(geomorph: Geomorph) -> (Framebuffer, Framebuffer) {
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path(), 33);
    let mode = PagerMode::Stepped {
        fetches_per_update: 64,
    };
    let lit = |streaming| {
        let mut s = settings(64 << 20, streaming, mode);
        s.level_set = LevelSet::PowerOfTwo;
        s.geomorph = geomorph;
        s.render.sampler = None;
        s
    };
    let mut whole = open(&path, lit(Streaming::Belts));
    let mut partial = open(&path, lit(progressive()));
    let (eye, target) = (
        DVec3::new(900.0, 900.0, 7200.0),
        DVec3::new(4000.0, 0.0, 3000.0),
    );
    let (mut a, mut b) = (frame(), frame());
    for engine in [&mut whole, &mut partial] {
        engine.hold_budget(6_000);
    }
    let (mut ra, mut rb) = (None, None);
    for k in 0..40 {
        for (engine, fb, report) in [
            (&mut whole, &mut a, &mut ra),
            (&mut partial, &mut b, &mut rb),
        ] {
            engine.set_time(f64::from(k));
            let camera = engine.camera(eye, target, false);
            *report = Some(engine.render(&camera, fb).unwrap());
        }
    }
    let (ra, rb) = (ra.unwrap(), rb.unwrap());
    assert!(rb.rendered.iter().all(|r| !r.capped));
    assert_eq!(
        (ra.pager.fetching, rb.pager.fetching),
        (0, 0),
        "settled: nothing in flight"
    );
    assert!(
        whole.pager().tiles().all(|(_, t)| t.is_complete()),
        "whole tiles"
    );
    assert!(
        partial.pager().tiles().any(|(_, t)| !t.is_complete()),
        "some tiles hold fewer levels than whole"
    );
    let mut drawn: Vec<usize> = rb.rendered.iter().map(|r| r.level).collect();
    drawn.sort_unstable();
    drawn.dedup();
    assert!(drawn.len() >= 3, "tiles drawn at several levels: {drawn:?}");
    let levels = |r: &FrameReport| {
        let mut l: Vec<_> = r.rendered.iter().map(|t| (t.id, t.level)).collect();
        l.sort_by_key(|&(id, _)| id);
        l
    };
    assert_eq!(levels(&ra), levels(&rb));
    (a, b)
}

#[test]
fn settled_partial_tiles_draw_exactly_what_whole_tiles_draw_lit() {
    // A tile drawn at a mask level is lit from the grid that level needs, whole or partial,
    // so the untextured pictures agree byte for byte.
    let (a, b) = settled_whole_and_partial(Geomorph::Off);
    assert!(
        a.to_rgba_image() == b.to_rgba_image(),
        "the pictures differ"
    );
}

#[test]
fn partial_tiles_lit_after_they_arrived_draw_what_tiles_loaded_lit_draw() {
    // Textured and unlit, the tiles hold no lighting; turned on, every held level of every
    // partial tile is lit in place, as tiles streamed lit from the start were.
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path(), 33);
    let mode = PagerMode::Stepped {
        fetches_per_update: 64,
    };
    let start = |lighting| {
        let mut s = settings(64 << 20, progressive(), mode);
        s.render.lighting = lighting;
        open(&path, s)
    };
    let (mut switched, mut lit) = (start(false), start(true));
    for engine in [&mut switched, &mut lit] {
        engine.hold_budget(6_000);
    }
    let (eye, target) = (
        DVec3::new(900.0, 900.0, 7200.0),
        DVec3::new(4000.0, 0.0, 3000.0),
    );
    let (mut a, mut b) = (frame(), frame());
    for k in 0..40 {
        if k == 30 {
            assert!(switched.pager().tiles().all(|(_, t)| t.normals.is_empty()));
            switched.render_settings_mut().lighting = true;
        }
        for (engine, fb) in [(&mut switched, &mut a), (&mut lit, &mut b)] {
            engine.set_time(f64::from(k));
            let camera = engine.camera(eye, target, false);
            let report = engine.render(&camera, fb).unwrap();
            check_memory(engine, &report);
        }
    }
    assert!(
        switched.pager().tiles().any(|(_, t)| !t.is_complete()),
        "some tiles hold fewer levels than whole"
    );
    assert!(
        switched
            .pager()
            .tiles()
            .all(|(_, t)| t.light.is_some() && t.normals.len() == t.side().pow(2))
    );
    assert!(
        a.to_rgba_image() == b.to_rgba_image(),
        "the pictures differ"
    );
}

#[test]
fn settled_partial_tiles_morph_exactly_as_whole_tiles_morph() {
    // A partial tile morphs the samples it holds exactly as the whole tile morphs them, so
    // with geomorphing on the pictures still agree byte for byte.
    let morphed = Geomorph::Distance { pixels: 16.0 };
    let (a, b) = settled_whole_and_partial(morphed);
    assert!(
        a.to_rgba_image() == b.to_rgba_image(),
        "the pictures differ"
    );
    let (plain, _) = settled_whole_and_partial(Geomorph::Off);
    assert!(
        a.to_rgba_image() != plain.to_rgba_image(),
        "the morph is at work in this view"
    );
}

/// Flies the first 15 s of the diagonal over a 256 kbit/s, 20 ms link on the simulated clock;
/// returns the engine and the flight time of the first drawn tile.
fn slow_link_flight(path: &std::path::Path, streaming: Streaming) -> (Engine, Option<f64>) {
    slow_link_flight_of(path, streaming, Builtin::Diagonal, 15.0)
}

/// Flies the first `seconds` of `builtin` over a 256 kbit/s, 20 ms link on the simulated
/// clock; returns the engine and the flight time of the first drawn tile.
fn slow_link_flight_of(
    path: &std::path::Path,
    streaming: Streaming,
    builtin: Builtin,
    seconds: f64,
) -> (Engine, Option<f64>) {
    let clock = Clock::Simulated {
        model: CostModel::HOST,
        slowdown: 10.0,
    };
    let link = LinkProfile {
        bandwidth_kbps: Some(256.0),
        latency: Duration::from_millis(20),
        ..LinkProfile::UNLIMITED
    };
    let (source, meter) = connect(
        source::open(path.to_str().unwrap()).unwrap(),
        Some(link),
        &clock,
    );
    let mut s = settings(4 << 20, streaming, PagerMode::Simulated { queue_depth: 4 });
    s.budget.expected = Some(clock.expected_cost(160, 120));
    let mut engine = Engine::new(source, s, Viewport::new(160, 120)).unwrap();
    engine.set_transfer_clock(meter.unwrap());
    let flight = Flight::builtin(builtin, engine.terrain());
    let mut fb = frame();
    let (mut t, mut first) = (0.0, None);
    while t < seconds.min(flight.duration()) {
        let (eye, target) = flight.at(t);
        let camera = engine.camera(eye, target, flight.above_ground);
        engine.set_time(t);
        let report = engine.render(&camera, &mut fb).unwrap();
        check_memory(&engine, &report);
        if report.rendered_tiles > 0 {
            first = first.or(Some(t));
        }
        t += clock.frame_seconds(&report);
        engine.record_frame(clock.frame_seconds(&report), report.draw.triangles as usize);
    }
    (engine, first)
}

#[test]
fn over_a_slow_link_progressive_tiles_cost_fewer_bytes_and_the_base_comes_first() {
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path(), 33);
    let (belts, belts_first) = slow_link_flight(&path, Streaming::Belts);
    let (stream, stream_first) = slow_link_flight(&path, progressive());
    let (bb, sb) = (
        belts.pager().stats().downloaded_bytes,
        stream.pager().stats().downloaded_bytes,
    );
    assert!(sb * 3 < bb, "progressive {sb} bytes, whole tiles {bb}");
    // Both draw the top first, as soon as it arrived (not before the link's latency).
    assert!(stream_first.unwrap() <= belts_first.unwrap());
    assert!(stream_first.unwrap() >= 0.02);
    let stats = stream.stream_stats().unwrap();
    assert!(stats.view_rendered_share().unwrap() > 0.5, "{stats:?}");
    // The pager's downloads are the streamed levels (with the index pages read to find them)
    // and the top.
    let reader = ArchiveReader::open(source::open(path.to_str().unwrap()).unwrap()).unwrap();
    assert_eq!(stats.received_bytes + reader.top().unwrap().1, sb);
}

#[test]
fn levels_are_not_asked_for_tiles_that_leave_the_view_before_they_arrive() {
    // The low flight passes over tiles and turns: without looking ahead, a tile near the eye
    // asks for a finer level in its last frames in view, which arrives after it left.
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path(), 33);
    let streaming = Streaming::Progressive(StreamSettings {
        prediction: None,
        ..StreamSettings::default()
    });
    let (engine, _) = slow_link_flight_of(&path, streaming, Builtin::Low, 60.0);
    let stats = engine.stream_stats().unwrap();
    assert!(stats.round_trip().is_some_and(|r| r > 0.0), "{stats:?}");
    // The first frame that draws stands on the ground the top brought in its update, so it
    // asks for what the view near it needs too.
    let (settled, rendered) = (stats.view_settled_bytes, stats.view_rendered_bytes);
    assert!(settled > 50_000, "{stats:?}");
    // Without looking ahead to the arrival, tiles passing behind the eye ask for levels that
    // arrive after they left.
    assert!(
        rendered as f64 >= 0.985 * settled as f64,
        "the bytes the view asked for are drawn within a second: \
         {rendered} of {settled}; {stats:?}"
    );
}

#[test]
fn the_fetch_thread_streams_levels_too() {
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path(), 33);
    let mode = PagerMode::Threaded { queue_depth: 2 };
    let mut engine = open(&path, settings(2 << 20, progressive(), mode));
    let (eye, target) = (
        DVec3::new(900.0, 900.0, 7200.0),
        DVec3::new(4000.0, 0.0, 3000.0),
    );
    let mut fb = frame();
    let started = std::time::Instant::now();
    let settled = loop {
        let camera = engine.camera(eye, target, false);
        let report = engine.render(&camera, &mut fb).unwrap();
        check_memory(&engine, &report);
        let received = engine.stream_stats().unwrap().received_bytes;
        if report.rendered_tiles > 0 && report.rendered.iter().all(|r| !r.capped) && received > 0 {
            break true;
        }
        if started.elapsed().as_secs() > 30 {
            break false;
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    };
    assert!(settled, "{:?}", engine.pager().stats());
    let stats = engine.stream_stats().unwrap();
    assert!(stats.requests > 0 && stats.received_bytes > 0);
    assert_eq!(engine.pager().stats().errors, 0);
}

/// Renders `frames` frames of a still view half a second apart; returns the last report.
fn hold_still(engine: &mut Engine, frames: u32) -> FrameReport {
    let (eye, target) = (
        DVec3::new(900.0, 900.0, 7200.0),
        DVec3::new(4000.0, 0.0, 3000.0),
    );
    let mut fb = frame();
    let mut last = None;
    for k in 0..frames {
        let camera = engine.camera(eye, target, false);
        engine.set_time(0.5 * f64::from(k));
        let report = engine.render(&camera, &mut fb).unwrap();
        check_memory(engine, &report);
        last = Some(report);
    }
    last.unwrap()
}

#[test]
fn a_view_is_complete_by_the_reference_budget_whatever_budget_its_frames_had() {
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path(), 33);
    let mode = PagerMode::Stepped {
        fetches_per_update: 4,
    };
    let streaming = Streaming::Progressive(StreamSettings {
        prediction: None,
        ..StreamSettings::default()
    });
    let (low, high) = (1_000, 40_000);
    // Frames held at a low budget ask for little: the view holds what that budget draws, not
    // what a higher reference budget would.
    let mut stingy = open(&path, settings(4 << 20, streaming, mode));
    stingy.hold_budget(low);
    let report = hold_still(&mut stingy, 60);
    assert!(report.rendered.iter().all(|r| !r.capped), "settled");
    assert!(stingy.holds_view(&report.view.camera, 7, &[low]));
    assert!(!stingy.holds_view(&report.view.camera, 7, &[high]));
    // Against several budgets, a tile needs the fewest levels any of them gives it.
    assert!(stingy.holds_view(&report.view.camera, 7, &[high, low]));
    // Frames at the high budget fetch what it draws.
    let mut generous = open(&path, settings(4 << 20, streaming, mode));
    generous.hold_budget(high);
    let report = hold_still(&mut generous, 60);
    assert!(generous.holds_view(&report.view.camera, 7, &[high]));
    // Whole tiles hold every level once loaded, whatever the budget.
    let mut belts = open(&path, settings(4 << 20, Streaming::Belts, mode));
    belts.hold_budget(low);
    let report = hold_still(&mut belts, 60);
    assert!(belts.holds_view(&report.view.camera, 7, &[high]));
}

/// The level-0 tiles holding more than their coarsest level.
fn refined(engine: &Engine) -> Vec<TileId> {
    let mut ids: Vec<TileId> = engine
        .pager()
        .tiles()
        .filter(|(id, t)| id.level == 0 && t.held_levels() > 1)
        .map(|(id, _)| id)
        .collect();
    ids.sort();
    ids
}

/// Gentle ripples 30 m apart with one tall peak in tile (5, 4): the peak's relief gives its
/// tile the largest share of visual importance in a view across it, though from afar it shows
/// little error.
fn peak_archive(dir: &std::path::Path) -> std::path::PathBuf {
    let options = BuildOptions {
        tile_size: 33,
        spacing: Some(30.0),
        texture_factor: 1,
        ..BuildOptions::default()
    };
    synthetic(dir, "peak", (257, 257), &options, |i, j| {
        let (i, j) = (i as f32, j as f32);
        let ripples = 10.0 * (i * 0.7).sin() * (j * 0.6).cos();
        let r2 = (i - 176.0).powi(2) + (j - 144.0).powi(2);
        400.0 + ripples + 600.0 * (-r2 / 60.0).exp()
    })
}

#[test]
fn the_worst_looking_tile_is_refined_first() {
    let dir = tempfile::tempdir().unwrap();
    let path = peak_archive(dir.path());
    // One request a frame: the order of the requests is the order tiles are refined in.
    let mode = PagerMode::Stepped {
        fetches_per_update: 1,
    };
    let mut engine = open(&path, settings(4 << 20, progressive(), mode));
    // Low over tile (1, 4), looking east across the peak: the tile under the eye shows the
    // largest error at its coarsest level, the peak's the largest share of importance.
    let (eye, target) = (
        DVec3::new(1440.0, 30.0, 4320.0),
        DVec3::new(5280.0, 0.0, 4320.0),
    );
    let mut fb = frame();
    let mut k = 0;
    while refined(&engine).is_empty() {
        // The cut reaches level 0 a tile a frame, then the first refinement comes.
        assert!(k < 100, "nothing refined in a hundred frames");
        let camera = engine.camera(eye, target, true);
        engine.set_time(0.5 * f64::from(k));
        engine.render(&camera, &mut fb).unwrap();
        k += 1;
    }
    assert_eq!(refined(&engine), vec![TileId::new(1, 4)]);
}

/// The first frame a camera placed before the top arrived is drawn with stands where
/// `Engine::camera` places it once the ground under it is held: not under the terrain.
#[test]
fn the_frame_the_top_arrives_for_stands_on_its_ground() {
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path(), 33);
    for streaming in [progressive(), Streaming::Belts] {
        // The top only: a level fetched in the frame would change the ground under the eye.
        let mode = PagerMode::Stepped {
            fetches_per_update: 0,
        };
        let mut engine = open(&path, settings(4 << 20, streaming, mode));
        let flight = Flight::builtin(Builtin::Low, engine.terrain());
        let (eye, target) = flight.at(0.0);
        let before = engine.camera(eye, target, true);
        assert!(engine.ground(before.position).is_none(), "nothing held yet");
        let report = engine.render(&before, &mut frame()).unwrap();
        let ground = engine
            .ground(report.view.camera.position)
            .expect("the top arrived");
        let placed = engine.camera(eye, target, true);
        assert!(
            before.position.y < ground,
            "placed under the ground it did not know"
        );
        assert!(
            (report.view.camera.position - placed.position).length() < 1e-9,
            "{:?} drawn from, {:?} placed now",
            report.view.camera.position,
            placed.position
        );
        assert!(report.view.camera.position.y > ground);
    }
}
