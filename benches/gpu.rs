//! The CPU rasterizer against the wgpu comparison backend on the same frames: the PocketPC frame
//! (320x240 RGB565, 16-bit depth, 10k triangles; CPU on one thread) and the workstation frame
//! (1280x720 RGBA8888, 32-bit depth, 440k triangles; CPU on all threads). On a machine without a
//! GPU the adapter is Mesa's llvmpipe (lavapipe), which uses every core.
//!
//! `cargo bench --features wgpu --bench gpu`. Per frame, the GPU times include what the GPU path
//! must do that the CPU path does not: uploading the vertices, indices and texture of the draw
//! (`gpu_frame_no_readback` stops there, after the GPU has finished), and reading the picture back
//! (`gpu_frame`). `gpu_readback_only` is a clear and a readback, the fixed cost per frame.

#[path = "../raster/tests/it/scene.rs"]
mod scene;

use criterion::{Criterion, criterion_group, criterion_main};
use stripmask_platform::GpuTarget;
use stripmask_raster::*;

fn frame(
    c: &mut Criterion,
    name: &str,
    grid: u32,
    size: (u32, u32),
    color: ColorFormat,
    depth: DepthFormat,
    threads: usize,
) {
    let s = scene::terrain(grid, size.0, size.1);
    let state = s.state();
    let sky = [150, 180, 220];
    let mut g = c.benchmark_group(name);
    let mut fb = Framebuffer::new(size.0, size.1, color, depth).unwrap();
    let mut rasterizer = Rasterizer::with_threads(threads);
    g.bench_function(format!("cpu_{threads}threads"), |b| {
        b.iter(|| {
            let mut cpu = RasterTarget::new(&mut fb, &mut rasterizer);
            cpu.clear(sky);
            cpu.draw(&s.mesh(), &s.transform, &state).unwrap()
        })
    });
    let mut gpu = match GpuTarget::new(size.0, size.1, color, depth) {
        Ok(gpu) => gpu,
        Err(e) => {
            eprintln!("{name}: GPU frames skipped: {e}");
            return;
        }
    };
    eprintln!("{name}: adapter {}", gpu.adapter_name());
    g.bench_function("gpu_frame", |b| {
        b.iter(|| {
            gpu.clear(sky);
            gpu.draw(&s.mesh(), &s.transform, &state).unwrap();
            gpu.read_image().unwrap()
        })
    });
    g.bench_function("gpu_frame_no_readback", |b| {
        b.iter(|| {
            gpu.clear(sky);
            gpu.draw(&s.mesh(), &s.transform, &state).unwrap();
            gpu.flush().unwrap()
        })
    });
    g.bench_function("gpu_readback_only", |b| {
        b.iter(|| {
            gpu.clear(sky);
            gpu.read_image().unwrap()
        })
    });
    g.finish();
}

fn frames(c: &mut Criterion) {
    frame(
        c,
        "pocketpc_320x240_rgb565_10k",
        72,
        (320, 240),
        ColorFormat::Rgb565,
        DepthFormat::D16,
        1,
    );
    frame(
        c,
        "workstation_1280x720_rgba8888_440k",
        470,
        (1280, 720),
        ColorFormat::Rgba8888,
        DepthFormat::D32,
        rayon::current_num_threads(),
    );
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = frames
}
criterion_main!(benches);
