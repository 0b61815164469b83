//! Rasterizer throughput on terrain-like strip meshes, and what each rendering feature costs.
//!
//! `cargo bench --bench raster`. Frames: the paper's PocketPC maximum (320x240 RGB565, 10k
//! textured, depth-tested, shaded triangles, one thread) and its workstation frame (1280x720,
//! 440k triangles, all threads). Feature costs: the PocketPC frame with one feature changed at a
//! time, to be read as ratios against `all_features` measured in the same run.

#[path = "../raster/tests/it/scene.rs"]
mod scene;

use std::time::Duration;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
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
    let mut fb = Framebuffer::new(size.0, size.1, color, depth).unwrap();
    let mut r = Rasterizer::with_threads(threads);
    let state = s.state();
    let stats = r.draw(&mut fb, &s.mesh(), &s.transform, &state).unwrap();
    let mut g = c.benchmark_group("frame");
    g.throughput(Throughput::Elements(scene::Scene::triangles(grid)));
    g.bench_function(format!("{name} ({} px written)", stats.fragments), |b| {
        b.iter(|| {
            fb.clear([150, 180, 220]);
            r.draw(&mut fb, &s.mesh(), &s.transform, &state).unwrap()
        })
    });
    g.finish();
}

fn frames(c: &mut Criterion) {
    frame(
        c,
        "pocketpc_320x240_rgb565_10k_1thread",
        72,
        (320, 240),
        ColorFormat::Rgb565,
        DepthFormat::D16,
        1,
    );
    let threads = rayon::current_num_threads();
    frame(
        c,
        &format!("workstation_1280x720_rgba8888_440k_{threads}threads"),
        470,
        (1280, 720),
        ColorFormat::Rgba8888,
        DepthFormat::D32,
        threads,
    );
}

fn features(c: &mut Criterion) {
    let s = scene::terrain(72, 320, 240);
    let mut g = c.benchmark_group("feature_cost_320x240_10k");
    g.throughput(Throughput::Elements(scene::Scene::triangles(72)));
    let base = s.state();
    let variants: Vec<(&str, RenderState, DepthFormat)> = vec![
        ("all_features", base, DepthFormat::D16),
        (
            "flat_only",
            RenderState {
                shading: Shading::Flat([200; 3]),
                texture: None,
                depth: DepthMode::NONE,
                ..base
            },
            DepthFormat::None,
        ),
        (
            "no_depth",
            RenderState {
                depth: DepthMode::NONE,
                ..base
            },
            DepthFormat::None,
        ),
        ("depth32", base, DepthFormat::D32),
        (
            "no_texture",
            RenderState {
                texture: None,
                ..base
            },
            DepthFormat::D16,
        ),
        (
            "no_shading",
            RenderState {
                shading: Shading::Flat([255; 3]),
                ..base
            },
            DepthFormat::D16,
        ),
        (
            "fog",
            RenderState {
                fog: Some(Fog {
                    color: [150, 180, 220],
                    start: 4e4,
                    end: 2e5,
                }),
                ..base
            },
            DepthFormat::D16,
        ),
        (
            "nearest",
            RenderState {
                texture: Some(TextureBinding::new(&s.texture, Sampler::NEAREST)),
                ..base
            },
            DepthFormat::D16,
        ),
        (
            "bilinear_no_mips",
            RenderState {
                texture: Some(TextureBinding::new(&s.texture, Sampler::BILINEAR)),
                ..base
            },
            DepthFormat::D16,
        ),
        (
            "perspective_exact",
            RenderState {
                perspective: Perspective::Exact,
                ..base
            },
            DepthFormat::D16,
        ),
        (
            "perspective_spans8",
            RenderState {
                perspective: Perspective::Spans(8),
                ..base
            },
            DepthFormat::D16,
        ),
        (
            "perspective_spans32",
            RenderState {
                perspective: Perspective::Spans(32),
                ..base
            },
            DepthFormat::D16,
        ),
        (
            "perspective_affine",
            RenderState {
                perspective: Perspective::Affine,
                ..base
            },
            DepthFormat::D16,
        ),
        (
            "float_reference",
            RenderState {
                precision: Precision::Float,
                ..base
            },
            DepthFormat::D16,
        ),
    ];
    for (name, state, depth) in variants {
        let mut fb = Framebuffer::new(320, 240, ColorFormat::Rgb565, depth).unwrap();
        let mut r = Rasterizer::with_threads(1);
        g.bench_function(name, |b| {
            b.iter(|| {
                fb.clear([150, 180, 220]);
                r.draw(&mut fb, &s.mesh(), &s.transform, &state).unwrap()
            })
        });
    }
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20).measurement_time(Duration::from_secs(3)).warm_up_time(Duration::from_secs(1));
    targets = frames, features
}
criterion_main!(benches);
