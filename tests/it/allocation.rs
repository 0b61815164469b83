//! The budget shared by projected error against the paper's share by importance, end to end
//! over views of the hills: never more than the budget, never a larger worst projected error
//! than importance with the same budget, and with budget to spare exactly the levels τ asks.

use glam::DVec3;
use proptest::prelude::*;
use proptest::test_runner::{Config, TestRunner};
use stripmask::engine::allocation::Allocation;
use stripmask::engine::{Engine, EngineSettings, FrameTiming};
use stripmask::{Bound, ErrorBound};
use stripmask_raster::Framebuffer;

/// An engine over the hills archive with every tile loaded, τ off, and the cut following τ
/// alone, so that both shares see the same tiles whatever the last frame's budget left.
fn loaded(dir: &std::path::Path) -> (Engine, Framebuffer) {
    crate::error_bound::loaded_with(
        &crate::support::hills::archive(dir, 33),
        EngineSettings {
            max_error: ErrorBound::Off,
            fit_cut_to_budget: false,
            frame_timing: FrameTiming::Told,
            ..EngineSettings::default()
        },
    )
}

fn views() -> impl Strategy<Value = ((f64, f64, f64), (f64, f64))> {
    (
        (0.0..7680.0f64, 0.0..7680.0f64, 30.0..3000.0f64),
        (0.0..7680.0f64, 0.0..7680.0f64),
    )
}

#[test]
fn by_error_spends_at_most_the_budget_and_is_never_worse_at_its_worst() {
    let dir = tempfile::tempdir().unwrap();
    let state = std::cell::RefCell::new(loaded(dir.path()));
    let mut runner = TestRunner::new(Config {
        cases: 48,
        ..Config::default()
    });
    let better = std::cell::Cell::new(0);
    runner
        .run(
            &(views(), 200usize..8_000),
            |(((x, z, up), (tx, tz)), budget)| {
                let (engine, fb) = &mut *state.borrow_mut();
                let camera = engine.camera(DVec3::new(x, up, z), DVec3::new(tx, 0.0, tz), true);
                let mut reports = Vec::new();
                for allocation in [Allocation::Importance, Allocation::Error] {
                    engine.set_allocation(allocation);
                    engine.hold_budget(budget);
                    let report = engine.render(&camera, fb).unwrap();
                    prop_assert_eq!(report.allocation, allocation);
                    reports.push(report);
                }
                let (importance, error) = (&reports[0], &reports[1]);
                prop_assert_eq!(importance.rendered.len(), error.rendered.len());
                let floor = 2 * error.rendered.len();
                prop_assert!(
                    error.triangles <= budget || error.rendered.iter().all(|r| r.level == 31),
                    "{} triangles over a budget of {}",
                    error.triangles,
                    budget.max(floor)
                );
                prop_assert!(
                    error.max_error_px <= importance.max_error_px + 1e-9,
                    "by error {} px, by importance {} px",
                    error.max_error_px,
                    importance.max_error_px
                );
                if error.max_error_px < importance.max_error_px {
                    better.set(better.get() + 1);
                }
                Ok(())
            },
        )
        .unwrap();
    let better = better.get();
    assert!(better > 10, "by error was better in only {better} views");
}

#[test]
fn with_budget_to_spare_by_error_draws_exactly_what_tau_asks() {
    let dir = tempfile::tempdir().unwrap();
    let state = std::cell::RefCell::new(loaded(dir.path()));
    let mut runner = TestRunner::new(Config {
        cases: 24,
        ..Config::default()
    });
    runner
        .run(
            &(views(), prop::sample::select(vec![0.5, 1.0, 2.0, 4.0])),
            |(((x, z, up), (tx, tz)), tau)| {
                let (engine, fb) = &mut *state.borrow_mut();
                let camera = engine.camera(DVec3::new(x, up, z), DVec3::new(tx, 0.0, tz), true);
                engine.set_max_error(ErrorBound::Pixels(tau));
                let mut levels = Vec::new();
                for allocation in [Allocation::Importance, Allocation::Error] {
                    engine.set_allocation(allocation);
                    engine.hold_budget(10_000_000);
                    let report = engine.render(&camera, fb).unwrap();
                    prop_assert_eq!(report.bound, Bound::Error);
                    for r in &report.rendered {
                        prop_assert!(r.error_px <= tau + 1e-9, "{:?} over τ = {}", r, tau);
                    }
                    levels.push(report.rendered.iter().map(|r| r.level).collect::<Vec<_>>());
                }
                prop_assert_eq!(&levels[0], &levels[1]);
                Ok(())
            },
        )
        .unwrap();
}
