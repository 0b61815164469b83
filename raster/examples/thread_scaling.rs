//! What a second thread buys one big draw: the peers' benchmark's scene B in size (1280x720,
//! a 470x470 grid of strips, 439,922 triangles) drawn by a one-thread and a two-thread
//! rasterizer taking turns, frame by frame, so that a shared machine's load falls on both alike.
//! For the peers' state (RGBA8888, 32-bit depth, bilinear, exact perspective) and the terrain
//! default (RGB565, 16-bit depth, mipmapped bilinear, spans of 16) it prints the median frame
//! times and the median of the per-frame ratios (one thread's time over two threads').
//!
//! ```sh
//! cargo run --release -p stripmask-raster --example thread_scaling -- 40
//! ```

#[path = "../tests/it/scene.rs"]
mod scene;

use std::time::Instant;

use stripmask_raster::*;

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let frames: usize = match std::env::args().nth(1).map(|a| a.parse()) {
        None => 20,
        Some(Ok(n)) if n > 0 => n,
        _ => {
            eprintln!("thread_scaling: the frame count must be a positive number");
            std::process::exit(2);
        }
    };
    let s = scene::terrain(470, 1280, 720);
    let peers = RenderState {
        shading: Shading::Gouraud,
        texture: Some(TextureBinding::new(
            &s.texture,
            Sampler {
                wrap: Wrap::Repeat,
                ..Sampler::BILINEAR
            },
        )),
        perspective: Perspective::Exact,
        ..RenderState::default()
    };
    let cases = [
        (
            "peers' state",
            ColorFormat::Rgba8888,
            DepthFormat::D32,
            peers,
        ),
        (
            "terrain default",
            ColorFormat::Rgb565,
            DepthFormat::D16,
            s.state(),
        ),
    ];
    println!(
        "{} triangles at 1280x720, {frames} frames each, {} threads in the pool",
        scene::Scene::triangles(470),
        rayon::current_num_threads()
    );
    for (name, color, depth, state) in cases {
        let mut fbs = [1, 2].map(|_| Framebuffer::new(1280, 720, color, depth).expect("valid"));
        let mut rs = [Rasterizer::with_threads(1), Rasterizer::with_threads(2)];
        let (mut times, mut ratios) = ([Vec::new(), Vec::new()], Vec::new());
        for f in 0..frames + 1 {
            let mut t = [0.0; 2];
            // Taking turns to go first.
            for k in [f % 2, 1 - f % 2] {
                let start = Instant::now();
                fbs[k].clear([140, 180, 230]);
                rs[k]
                    .draw(&mut fbs[k], &s.mesh(), &s.transform, &state)
                    .expect("the scene is valid");
                t[k] = start.elapsed().as_secs_f64();
            }
            // The first frame sizes the scratch buffers: not counted.
            if f > 0 {
                times[0].push(t[0]);
                times[1].push(t[1]);
                ratios.push(t[0] / t[1]);
            }
        }
        assert!(fbs[0] == fbs[1], "one and two threads give the same bytes");
        println!(
            "{name}: 1 thread {:.1} ms, 2 threads {:.1} ms, median ratio {:.2}",
            median(&mut times[0]) * 1e3,
            median(&mut times[1]) * 1e3,
            median(&mut ratios)
        );
    }
}
