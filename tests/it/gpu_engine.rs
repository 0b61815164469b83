//! The engine's frame through both draw targets: `Engine::render` (the CPU rasterizer) and
//! `Engine::render_to` a `GpuTarget` send the same draw list, so the pictures agree up to the two
//! rasterizers' differences. Skipped, with a message, on a machine without a GPU adapter.

use std::io::Write;

use glam::DVec3;
use stripmask::Viewport;
use stripmask::db::source;
use stripmask::engine::paging::PagerMode;
use stripmask::engine::{Engine, EngineSettings, FrameTiming};
use stripmask_platform::{GpuTarget, PlatformError};
use stripmask_raster::{ColorFormat, DepthFormat, Framebuffer};

use crate::support::hills;

#[test]
fn an_engine_frame_on_the_gpu_matches_the_cpu_frame() {
    let (color, depth) = (ColorFormat::Rgb565, DepthFormat::D16);
    let mut gpu = match GpuTarget::new(320, 240, color, depth) {
        Ok(gpu) => gpu,
        Err(e @ PlatformError::NoGpuAdapter { .. }) => {
            let _ = writeln!(std::io::stderr(), "gpu_engine: skipped, {e}");
            return;
        }
        Err(e) => panic!("GPU target: {e}"),
    };
    let dir = tempfile::tempdir().unwrap();
    let path = hills::archive(dir.path(), 33);
    let settings = EngineSettings {
        memory_limit_bytes: 64 << 20,
        pager_mode: PagerMode::Stepped {
            fetches_per_update: 64,
        },
        threads: 1,
        frame_timing: FrameTiming::Told,
        ..EngineSettings::default()
    };
    let mut engine = Engine::new(
        source::open(path.to_str().unwrap()).unwrap(),
        settings,
        Viewport::new(320, 240),
    )
    .unwrap();
    let mut fb = Framebuffer::new(320, 240, color, depth).unwrap();
    let (eye, target) = (
        DVec3::new(1200.0, 1500.0, 3900.0),
        DVec3::new(4000.0, 300.0, 2000.0),
    );
    for _ in 0..4 {
        engine
            .render(&engine.camera(eye, target, false), &mut fb)
            .unwrap();
    }
    let camera = engine.camera(eye, target, false);
    let on_cpu = engine.render(&camera, &mut fb).unwrap();
    let on_gpu = engine.render_to(&camera, &mut gpu).unwrap();
    assert!(on_cpu.rendered_tiles > 4);
    assert_eq!(on_gpu.rendered, on_cpu.rendered, "the same draw list");
    assert_eq!(on_gpu.draw.triangles, on_cpu.draw.triangles);

    let (cpu, gpu_image) = (fb.to_rgba_image(), gpu.read_image().unwrap());
    let (mut squared, mut off) = (0.0f64, 0usize);
    for (p, q) in cpu.pixels().zip(gpu_image.pixels()) {
        let d = [0, 1, 2].map(|k| i32::from(p.0[k]) - i32::from(q.0[k]));
        squared += d.iter().map(|&v| f64::from(v * v)).sum::<f64>();
        off += usize::from(d.iter().any(|v| v.abs() > 40));
    }
    let pixels = f64::from(320 * 240);
    let psnr = 10.0 * (255.0f64.powi(2) / (squared / (3.0 * pixels))).log10();
    let off = off as f64 / pixels;
    let _ = writeln!(
        std::io::stderr(),
        "gpu_engine: {}: PSNR {psnr:.1} dB, {:.2}% of pixels off by more than 40",
        gpu.adapter_name(),
        100.0 * off
    );
    // Measured on llvmpipe: 36.4 dB, 0.02 % of pixels off.
    assert!(psnr > 32.0 && off < 0.003, "PSNR {psnr} dB, {off} off");
}

#[test]
fn the_tradeoff_report_measures_every_setting_against_the_gpu_reference_too() {
    use stripmask::sim::tradeoff::reference::{CpuFloat, Gpu, Reference};
    use stripmask::sim::tradeoff::{TradeoffOptions, run_with};
    let size = (160, 120);
    let gpu = match Gpu::new(size) {
        Ok(gpu) => gpu,
        Err(e @ PlatformError::NoGpuAdapter { .. }) => {
            let _ = writeln!(std::io::stderr(), "gpu_engine: skipped, {e}");
            return;
        }
        Err(e) => panic!("GPU reference: {e}"),
    };
    let _ = writeln!(std::io::stderr(), "gpu_engine: adapter {}", gpu.adapter());
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("report");
    let options = TradeoffOptions {
        source: hills::archive(dir.path(), 33).display().to_string(),
        out: out.clone(),
        flight: None,
        flight_views: 0,
        builtin_views: Some(2),
        size,
        repeats: 1,
        threshold: 16,
        knobs: Some(vec!["budget".into()]),
        max_error: stripmask::ErrorBound::default(),
        allocation: stripmask::engine::allocation::Allocation::default(),
        progress: false,
    };
    let references: Vec<Box<dyn Reference>> = vec![Box::new(CpuFloat), Box::new(gpu)];
    let report = run_with(&options, references).unwrap();
    for row in &report.rows {
        assert_eq!(row.measurement.errors.len(), 2, "{}", row.entry.name);
    }
    let full = report
        .rows
        .iter()
        .find(|r| r.entry.name == "budget=full")
        .unwrap();
    let coarse = report
        .rows
        .iter()
        .find(|r| r.entry.name == "budget=3000")
        .unwrap();
    // The GPU reference ranks the budgets as the CPU one does.
    let gpu_error = |r: &stripmask::sim::tradeoff::Row| r.measurement.errors[1].ssim;
    assert!(
        gpu_error(full) > gpu_error(coarse),
        "{} {}",
        gpu_error(full),
        gpu_error(coarse)
    );
    let csv = std::fs::read_to_string(out.join("tradeoff.csv")).unwrap();
    assert!(csv.lines().next().unwrap().contains("wgpu_ssim"));
    assert!(out.join("reference-wgpu-0-overview.png").exists());
}
