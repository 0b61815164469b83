//! `stripmask tradeoff` on the small hills archive: two views, two knobs, one repeat.

use stripmask::sim::tradeoff::{TradeoffOptions, run};

use crate::support::hills;

fn options(source: String, out: std::path::PathBuf, knobs: &[&str]) -> TradeoffOptions {
    TradeoffOptions {
        source,
        out,
        flight: None,
        flight_views: 0,
        builtin_views: Some(2),
        size: (64, 48),
        repeats: 1,
        threshold: 16,
        knobs: Some(knobs.iter().map(|k| k.to_string()).collect()),
        max_error: stripmask::ErrorBound::default(),
        allocation: stripmask::engine::allocation::Allocation::default(),
        progress: false,
    }
}

#[test]
fn a_tiny_sweep_writes_its_table_csv_plot_and_references_and_ranks_the_budgets() {
    let dir = tempfile::tempdir().unwrap();
    let archive = hills::archive(dir.path(), 33).display().to_string();
    let out = dir.path().join("report");
    let report = run(&options(archive, out.clone(), &["budget", "precision"])).unwrap();

    // Defaults, 5 other budgets, float, and float at those 5 budgets.
    assert_eq!(report.rows.len(), 12);
    assert_eq!(report.rows[0].entry.name, "defaults");
    assert!((report.rows[0].ratio - 1.0).abs() < 1e-12);
    assert!(report.rows.iter().any(|r| r.pareto));
    let row = |name: &str| {
        report
            .rows
            .iter()
            .find(|r| r.entry.name == name)
            .unwrap_or_else(|| panic!("no row {name}"))
    };
    let (coarse, full) = (
        &row("budget=3000").measurement,
        &row("budget=full").measurement,
    );
    assert!(
        coarse.triangles <= 3000.0 && full.triangles > 5.0 * coarse.triangles,
        "{} and {} triangles",
        coarse.triangles,
        full.triangles
    );
    assert_eq!(
        full.geometric_max_px, 0.0,
        "full resolution has no geometric error"
    );
    assert!(coarse.geometric_max_px > 0.5, "{}", coarse.geometric_max_px);
    assert!(full.errors[0].ssim > coarse.errors[0].ssim);
    assert!(full.errors[0].mse < coarse.errors[0].mse);
    // Float at full resolution differs from the reference only by the RGB565 colour buffer.
    let reference_like = &row("budget=full precision=float").measurement.errors[0];
    assert!(reference_like.ssim > 0.98, "{}", reference_like.ssim);

    let csv = std::fs::read_to_string(out.join("tradeoff.csv")).unwrap();
    assert_eq!(csv.lines().count(), 13);
    assert!(csv.starts_with("setting,cpu_ms,ratio,wall_ms,triangles,"));
    assert!(csv.lines().next().unwrap().contains("cpu-float_ssim"));
    let md = std::fs::read_to_string(out.join("tradeoff.md")).unwrap();
    assert!(md.contains("| budget=3000 precision=float |") && md.contains("## Pareto front"));
    let plot = image::open(out.join("pareto.png")).unwrap();
    assert_eq!(
        (plot.width(), plot.height()),
        stripmask::sim::tradeoff::plot::SIZE
    );
    assert!(out.join("reference-cpu-float-0-overview.png").exists());
    assert!(out.join("reference-cpu-float-1-oblique.png").exists());
}

#[test]
fn an_unknown_knob_is_refused_with_the_list_of_knobs() {
    let dir = tempfile::tempdir().unwrap();
    let archive = hills::archive(dir.path(), 33).display().to_string();
    let e = run(&options(archive, dir.path().join("r"), &["geomorphs"]))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("\"geomorphs\"") && e.contains("perspective"),
        "{e}"
    );
}

#[test]
fn the_geomorph_knob_builds_morphing_engines_and_changes_the_picture() {
    let dir = tempfile::tempdir().unwrap();
    let archive = hills::archive(dir.path(), 33).display().to_string();
    let report = run(&options(archive, dir.path().join("r"), &["geomorph"])).unwrap();
    let names: Vec<&str> = report.rows.iter().map(|r| r.entry.name.as_str()).collect();
    assert_eq!(
        names,
        ["defaults", "geomorph=distance4", "geomorph=distance16"]
    );
    let mse = |k: usize| report.rows[k].measurement.errors[0].mse;
    assert_ne!(
        mse(0),
        mse(2),
        "a 16 px morph moves vertices in these views"
    );
}
