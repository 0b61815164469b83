//! The pixel-error bound τ end to end: when the budget allows, no drawn tile's projected error
//! exceeds τ and no tile is finer than τ needs; the budget controller does not wind up while τ
//! caps detail.

use glam::DVec3;
use proptest::prelude::*;
use proptest::test_runner::{Config, TestRunner};
use stripmask::Viewport;
use stripmask::db::source;
use stripmask::engine::frustum::Aabb;
use stripmask::engine::paging::PagerMode;
use stripmask::engine::{Engine, EngineSettings, FrameReport, FrameTiming};
use stripmask::{Bound, ErrorBound};
use stripmask_raster::{ColorFormat, DepthFormat, Framebuffer};

use crate::support::hills;

const HEIGHT: u32 = 120;

/// An engine over the hills archive with every tile of every level loaded.
pub(crate) fn loaded(dir: &std::path::Path, max_error: ErrorBound) -> (Engine, Framebuffer) {
    loaded_with(
        &hills::archive(dir, 33),
        EngineSettings {
            max_error,
            frame_timing: FrameTiming::Told,
            ..EngineSettings::default()
        },
    )
}

/// The same over the archive at `path` (257 x 257 samples, 30 m apart) with `settings` (all of
/// the archive fits in memory, one thread, stepped paging).
pub(crate) fn loaded_with(
    path: &std::path::Path,
    settings: EngineSettings,
) -> (Engine, Framebuffer) {
    let settings = EngineSettings {
        memory_limit_bytes: 1 << 30,
        pager_mode: PagerMode::Stepped {
            fetches_per_update: usize::MAX,
        },
        threads: 1,
        ..settings
    };
    let mut engine = Engine::new(
        source::open(path.to_str().unwrap()).unwrap(),
        settings,
        Viewport::new(160, HEIGHT),
    )
    .unwrap();
    let mut fb = Framebuffer::new(160, HEIGHT, ColorFormat::Rgb565, DepthFormat::D16).unwrap();
    // The whole terrain from high above, at full resolution: the cut asks for every tile of
    // every level, which come a level a frame.
    let bound = engine.settings().max_error;
    engine.set_max_error(ErrorBound::Off);
    let above = DVec3::new(3840.0, 40_000.0, 3841.0);
    let camera = engine.camera(above, DVec3::new(3840.0, 0.0, 3840.0), false);
    for _ in 0..6 {
        engine.render(&camera, &mut fb).unwrap();
    }
    engine.set_max_error(bound);
    let pager = engine.pager();
    let all = engine.terrain().pyramid().tile_count() as usize;
    assert_eq!(pager.stats().loaded_tiles + pager.stats().top_tiles, all);
    (engine, fb)
}

/// Pixels per metre of height error of tile `id` in `report`'s view, as the engine measures it:
/// at its box's nearest point, no nearer than the clearance.
fn pixels_per_metre(engine: &Engine, report: &FrameReport, id: stripmask::db::grid::TileId) -> f64 {
    let tile = engine.pager().get(id).unwrap();
    let (lo, hi) = engine
        .terrain()
        .tile_box(id, f64::from(tile.min), f64::from(tile.max));
    let eye = report.view.camera.position;
    let distance = Aabb::new(lo - eye, hi - eye).distance(DVec3::ZERO);
    let clearance = engine.settings().clearance;
    report.view.pixels_per_metre(distance.max(clearance))
}

#[test]
fn with_budget_to_spare_every_tile_is_the_coarsest_within_tau() {
    let dir = tempfile::tempdir().unwrap();
    let state = std::cell::RefCell::new(loaded(dir.path(), ErrorBound::default()));
    let views = (
        (0.0..7680.0f64, 0.0..7680.0f64, 30.0..3000.0f64),
        (0.0..7680.0f64, 0.0..7680.0f64),
        prop::sample::select(vec![0.5, 1.0, 2.0, 4.0]),
    );
    let mut runner = TestRunner::new(Config {
        cases: 40,
        ..Config::default()
    });
    runner
        .run(&views, |((x, z, up), (tx, tz), tau)| {
            let (engine, fb) = &mut *state.borrow_mut();
            engine.set_max_error(ErrorBound::Pixels(tau));
            engine.hold_budget(10_000_000);
            let camera = engine.camera(DVec3::new(x, up, z), DVec3::new(tx, 0.0, tz), true);
            let report = engine.render(&camera, fb).unwrap();
            prop_assert_eq!(report.bound, Bound::Error);
            let mut worst = 0.0f64;
            for r in &report.rendered {
                prop_assert!(r.error_px <= tau + 1e-9, "{:?} over τ = {}", r, tau);
                worst = worst.max(r.error_px);
                // The next coarser level would exceed τ: the tile is no finer than it needs
                // (unless it stitches to a tile of another pyramid level).
                if r.conformed {
                    continue;
                }
                let ppm = pixels_per_metre(engine, &report, r.id);
                let errors = &engine.pager().get(r.id).unwrap().level_errors;
                let coarser = engine.masks().levels().iter().filter(|&&l| l > r.level);
                for &l in coarser {
                    prop_assert!(
                        f64::from(errors[l]) * ppm > tau,
                        "{:?} could draw level {} within τ = {}",
                        r,
                        l,
                        tau
                    );
                }
            }
            prop_assert_eq!(report.max_error_px, worst);
            Ok(())
        })
        .unwrap();
}

#[test]
fn tau_never_draws_more_than_the_budget_alone_and_off_draws_every_tile_full() {
    let dir = tempfile::tempdir().unwrap();
    let (mut engine, mut fb) = loaded(dir.path(), ErrorBound::Off);
    let camera = engine.camera(
        DVec3::new(500.0, 300.0, 500.0),
        DVec3::new(4000.0, 0.0, 4000.0),
        true,
    );
    engine.hold_budget(10_000_000);
    let off = engine.render(&camera, &mut fb).unwrap();
    assert_eq!(off.bound, Bound::Full);
    assert!(off.rendered.iter().all(|r| r.level == 0));
    assert_eq!(off.max_error_px, 0.0);
    let mut previous = off.triangles;
    for tau in [0.5, 1.0, 2.0, 4.0] {
        engine.set_max_error(ErrorBound::Pixels(tau));
        let report = engine.render(&camera, &mut fb).unwrap();
        assert!(report.triangles <= previous, "τ = {tau}");
        previous = report.triangles;
    }
    assert!(
        previous < off.triangles / 2,
        "{previous} of {}",
        off.triangles
    );
    // A budget below the need binds, and says so.
    engine.hold_budget(previous / 2);
    let short = engine.render(&camera, &mut fb).unwrap();
    assert_eq!(short.bound, Bound::Budget);
    assert!(short.max_error_px > 4.0, "{}", short.max_error_px);
}

#[test]
fn the_budget_does_not_grow_while_tau_binds() {
    let dir = tempfile::tempdir().unwrap();
    let (mut engine, mut fb) = loaded(dir.path(), ErrorBound::default());
    let eye = DVec3::new(1000.0, 400.0, 1000.0);
    let mut budget = 20_000;
    engine.hold_budget(budget);
    let mut bound_frames = 0;
    for k in 0..60 {
        // Fly forward slowly; every frame takes a hundredth of the target's time.
        let step = DVec3::new(20.0, 0.0, 15.0) * f64::from(k);
        let camera = engine.camera(eye + step, DVec3::new(5000.0, 0.0, 4000.0), true);
        let report = engine.render(&camera, &mut fb).unwrap();
        assert_eq!(report.budget, budget);
        let next = engine.record_frame(0.0004, report.draw.triangles as usize);
        if report.bound == Bound::Error {
            bound_frames += 1;
            assert!(next <= budget, "frame {k}: {budget} -> {next}");
            assert!(next <= 2 * report.triangles.max(500), "frame {k}: {next}");
        }
        budget = next;
    }
    assert!(bound_frames > 50, "{bound_frames}");
}

/// Under a budget far below what τ needs, the second frame's cut stops where the first frame's
/// budget left more error than a tile's own samples show: fewer tiles, no more error.
#[test]
fn a_budget_that_cannot_meet_tau_cuts_no_deeper_than_it_can_use() {
    let dir = tempfile::tempdir().unwrap();
    let budget = 400;
    let settings = EngineSettings {
        budget: stripmask::engine::budget::BudgetSettings {
            min_budget: budget,
            max_budget: budget,
            initial_budget: budget,
            ..Default::default()
        },
        frame_timing: FrameTiming::Told,
        ..EngineSettings::default()
    };
    // Rough at the scale of a sample, so that the errors of the levels above 0, not their
    // texels, decide how deep the cut at τ goes.
    let options = stripmask::db::builder::BuildOptions {
        tile_size: 33,
        spacing: Some(30.0),
        texture_factor: 1,
        ..Default::default()
    };
    let rough = hills::synthetic(dir.path(), "rough", (257, 257), &options, |i, j| {
        400.0 + 20.0 * ((i * 7 + j * 13) % 5) as f32
    });
    let (mut engine, mut fb) = loaded_with(&rough, settings);
    let camera = engine.camera(
        DVec3::new(500.0, 900.0, 7000.0),
        DVec3::new(5000.0, 0.0, 1500.0),
        false,
    );
    let deep = engine.render(&camera, &mut fb).unwrap();
    let fitted = engine.render(&camera, &mut fb).unwrap();
    for report in [&deep, &fitted] {
        assert_eq!(report.bound, Bound::Budget);
        assert!(report.triangles <= budget);
    }
    assert!(
        fitted.rendered.len() < deep.rendered.len(),
        "the cut at τ draws {} tiles, the cut the budget can use {}",
        deep.rendered.len(),
        fitted.rendered.len()
    );
    assert!(
        fitted.max_error_px <= deep.max_error_px * 1.05,
        "fewer tiles show no more error: {} px against {} px",
        fitted.max_error_px,
        deep.max_error_px
    );
}
