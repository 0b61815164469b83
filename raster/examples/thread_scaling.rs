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
#[path = "support/turns.rs"]
mod turns;

use stripmask_raster::*;

fn main() {
    let frames = turns::frames_arg("thread_scaling", 20);
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
        let (times, ratio) = turns::take_turns(frames, |k| {
            fbs[k].clear([140, 180, 230]);
            rs[k]
                .draw(&mut fbs[k], &s.mesh(), &s.transform, &state)
                .expect("the scene is valid");
        });
        assert!(fbs[0] == fbs[1], "one and two threads give the same bytes");
        println!(
            "{name}: 1 thread {:.1} ms, 2 threads {:.1} ms, median ratio {ratio:.2}",
            times[0] * 1e3,
            times[1] * 1e3,
        );
    }
}
