//! The engine end to end on a synthetic archive: flights, statistics, memory, exactness far from
//! the origin, and watertight tiles.

use glam::DVec3;
use stripmask::Viewport;
use stripmask::db::source;
use stripmask::engine::{Engine, EngineSettings, FrameTiming};
use stripmask::sim::clock::Clock;
use stripmask::sim::flight::{Builtin, Flight};
use stripmask::sim::fly::{FlyOptions, Length, fly};
use stripmask::sim::stats::CSV_HEADER;
use stripmask_raster::{ColorFormat, DepthFormat, Framebuffer};

use crate::support::hills;
use hills::{archive, stepped};

/// Renders a few frames from one pose so that the stepped pager has loaded what it can.
fn settle(engine: &mut Engine, eye: DVec3, target: DVec3, fb: &mut Framebuffer) {
    for _ in 0..4 {
        let camera = engine.camera(eye, target, false);
        engine.render(&camera, fb).unwrap();
    }
}

#[test]
fn fly_writes_one_stats_row_per_frame_and_keeps_every_kth_frame() {
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path(), 33);
    let engine = stepped(2_000_000);
    let reader =
        stripmask::db::archive::ArchiveReader::open(source::open(path.to_str().unwrap()).unwrap())
            .unwrap();
    let terrain = stripmask::engine::terrain::TerrainFrame::new(reader.header());
    let out = dir.path().join("run");
    let summary = fly(&FlyOptions {
        source: path.display().to_string(),
        flight: Flight::builtin(Builtin::Diagonal, &terrain),
        length: Some(Length::Frames(25)),
        size: (160, 120),
        color: ColorFormat::Rgb565,
        depth: DepthFormat::D16,
        engine,
        out: out.clone(),
        every: 10,
        hud: true,
        progress: false,
        clock: Clock::default(),
        link: None,
        plots: false,
        http: stripmask::db::source::http::HttpOptions::default(),
    })
    .unwrap();
    assert_eq!(summary.frames, 25);
    assert!(summary.peak_memory_bytes <= 2_000_000);
    assert!(summary.downloaded_bytes > 0);
    assert_eq!(summary.holes.first_frame_s, Some(0.0));

    let csv = std::fs::read_to_string(out.join("stats.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(header, CSV_HEADER.split(',').collect::<Vec<_>>());
    for column in "frame,time_s,frame_ms,fps,target_fps,budget,triangles,rendered_tiles,loaded_tiles,memory_bytes,memory_limit_bytes,downloaded_bytes".split(',') {
        assert!(header.contains(&column), "{column}");
    }
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 25);
    for (k, r) in rows.iter().enumerate() {
        assert_eq!(r[col("frame")], k as f64);
        assert!(r[col("memory_bytes")] <= r[col("memory_limit_bytes")]);
        assert!(r[col("rendered_tiles")] <= r[col("loaded_tiles")]);
        assert!(r[col("triangles")] > 0.0);
    }
    let mut frames: Vec<_> = std::fs::read_dir(out.join("frames"))
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    frames.sort();
    assert_eq!(frames.len(), 3, "{frames:?}");
}

#[test]
fn a_terrain_far_from_the_origin_renders_the_same_picture() {
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path(), 33);
    // Dyadic positions, so that adding 10^7 or 10^8 m is exact and any difference is the engine's.
    let eye = DVec3::new(1200.5, 1500.25, 3900.75);
    let target = DVec3::new(4000.0, 300.0, 2000.0);
    let mut pictures = Vec::new();
    for offset in [0.0, 1e3, 1e7, 1e8] {
        let mut engine = Engine::new(
            source::open(path.to_str().unwrap()).unwrap(),
            stepped(64 << 20),
            Viewport::new(160, 120),
        )
        .unwrap();
        engine.place_terrain(DVec3::new(offset, -offset / 8.0, -offset));
        let (eye, target) = (
            engine.terrain().origin + eye,
            engine.terrain().origin + target,
        );
        let mut fb = Framebuffer::new(160, 120, ColorFormat::Rgba8888, DepthFormat::D32).unwrap();
        settle(&mut engine, eye, target, &mut fb);
        let report = engine
            .render(&engine.camera(eye, target, false), &mut fb)
            .unwrap();
        assert!(report.rendered_tiles > 4);
        pictures.push((offset, fb.to_rgba_image()));
    }
    for (offset, p) in &pictures[1..] {
        assert!(p == &pictures[0].1, "offset {offset} changed the picture");
    }
}

#[test]
fn neighbouring_tiles_at_the_same_level_leave_no_crack() {
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path(), 33);
    let mut settings = stepped(64 << 20);
    settings.budget.initial_budget = 1 << 20;
    settings.budget.min_budget = 1 << 20;
    settings.budget.max_budget = 1 << 20;
    settings.render.sky = [255, 0, 255];
    settings.render.fog = false;
    for precision in [
        stripmask_raster::Precision::Fixed,
        stripmask_raster::Precision::Float,
    ] {
        settings.render.precision = precision;
        let mut engine = Engine::new(
            source::open(path.to_str().unwrap()).unwrap(),
            settings,
            Viewport::new(320, 240),
        )
        .unwrap();
        let mut fb = Framebuffer::new(320, 240, ColorFormat::Rgb565, DepthFormat::D16).unwrap();
        // Oblique, looking across several tile borders, the horizon out of frame.
        let eye = DVec3::new(3840.0, 2500.0, 6400.0);
        let target = DVec3::new(3900.0, 0.0, 5000.0);
        settle(&mut engine, eye, target, &mut fb);
        let report = engine
            .render(&engine.camera(eye, target, false), &mut fb)
            .unwrap();
        assert!(report.rendered_tiles >= 9, "{}", report.rendered_tiles);
        let img = fb.to_rgba_image();
        let holes = img.pixels().filter(|p| p.0[..3] == [255, 0, 255]).count();
        assert_eq!(
            holes, 0,
            "{precision:?}: {holes} background pixels between tiles"
        );
    }
}

#[test]
fn a_texture_budget_coarsens_the_textures_of_the_square_to_fit() {
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path(), 33);
    // Viewer over the centre tile; the limit holds the 5 x 5 square around it.
    let eye = DVec3::new(4.5 * 960.0, 1500.0, 4.5 * 960.0);
    let target = eye + DVec3::new(10.0, -30.0, 0.0);
    let texture_bytes = |budget: Option<usize>| {
        let mut settings = stepped(25 * 40_000);
        settings.texture_budget_bytes = budget;
        let mut engine = Engine::new(
            source::open(path.to_str().unwrap()).unwrap(),
            settings,
            Viewport::new(160, 120),
        )
        .unwrap();
        let mut fb = Framebuffer::new(160, 120, ColorFormat::Rgb565, DepthFormat::D16).unwrap();
        settle(&mut engine, eye, target, &mut fb);
        let stats = engine.pager().stats();
        assert!(stats.memory_peak_bytes <= 25 * 40_000);
        engine
            .pager()
            .tiles()
            .map(|(_, t)| t.texture.byte_size())
            .sum::<usize>()
    };
    let free = texture_bytes(None);
    let capped = texture_bytes(Some(free / 3));
    assert!(capped <= free / 3, "{capped} of {} allowed", free / 3);
    assert!(capped > 0);
}

/// An engine over the hills for a 160x120 viewport, every tile it wants fetched in a frame.
fn embedded(path: &std::path::Path, settings: EngineSettings) -> Engine {
    let source = source::open(path.to_str().unwrap()).unwrap();
    Engine::new(source, settings, Viewport::new(160, 120)).unwrap()
}

#[test]
fn a_camera_under_the_ground_is_drawn_where_it_is_unless_lifting_is_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path(), 33);
    for lift in [false, true] {
        let mut engine = embedded(
            &path,
            EngineSettings {
                lift_to_clearance: lift,
                ..stepped(64 << 20)
            },
        );
        let mut fb = Framebuffer::new(160, 120, ColorFormat::Rgb565, DepthFormat::D16).unwrap();
        // Placed before any ground is held: 1 m above the archive's lowest height.
        let low = engine.terrain().heights.0 + 1.0;
        let camera = stripmask::Camera::looking_at(
            DVec3::new(2000.0, low, 2000.0),
            DVec3::new(3000.0, low, 2500.0),
        );
        let report = engine.render(&camera, &mut fb).unwrap();
        let ground = engine.ground(camera.position).expect("the top arrived");
        assert!(camera.position.y < ground, "the hills rise above the eye");
        if lift {
            assert!(report.view.camera.position.y >= ground + engine.settings().clearance);
        } else {
            assert_eq!(report.view.camera, camera, "the caller's camera as given");
        }
    }
}

#[test]
fn a_target_of_another_size_than_the_viewport_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let mut engine = embedded(&archive(dir.path(), 33), stepped(64 << 20));
    let mut fb = Framebuffer::new(320, 240, ColorFormat::Rgb565, DepthFormat::D16).unwrap();
    let camera = engine.camera(DVec3::new(0.0, 2000.0, 0.0), DVec3::splat(2000.0), false);
    let before = engine.pager().stats();
    let e = engine.render(&camera, &mut fb).unwrap_err().to_string();
    assert!(e.contains("320x240") && e.contains("160x120"), "{e}");
    assert_eq!(
        engine.pager().stats(),
        before,
        "a refused frame pages nothing"
    );
    engine.resize(320, 240).unwrap();
    engine.render(&camera, &mut fb).unwrap();
}

#[test]
fn the_budget_follows_measured_frames_without_being_told_and_stays_when_told_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path(), 33);
    let (eye, target) = (
        DVec3::new(1200.0, 1500.0, 3900.0),
        DVec3::new(4000.0, 300.0, 2000.0),
    );
    for timing in [FrameTiming::Measured, FrameTiming::Told] {
        let mut settings = stepped(64 << 20);
        settings.frame_timing = timing;
        // A frame rate no machine holds: every measured frame is too slow.
        settings.budget.target_fps = 1e9;
        let mut engine = embedded(&path, settings);
        let mut fb = Framebuffer::new(160, 120, ColorFormat::Rgb565, DepthFormat::D16).unwrap();
        let mut budgets = Vec::new();
        for _ in 0..6 {
            let report = engine
                .render(&engine.camera(eye, target, false), &mut fb)
                .unwrap();
            budgets.push(report.budget);
        }
        match timing {
            FrameTiming::Measured => assert!(budgets[5] < budgets[0], "{budgets:?}"),
            FrameTiming::Told => assert!(budgets.iter().all(|&b| b == budgets[0]), "{budgets:?}"),
        }
    }
}
