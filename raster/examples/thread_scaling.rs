//! What a second thread buys one big draw: the peers' benchmark's scene B in size (1280x720,
//! a 470x470 grid of strips, 439,922 triangles) drawn by a one-thread and a two-thread
//! rasterizer taking turns, frame by frame, so that a shared machine's load falls on both alike.
//! For the peers' state (RGBA8888, 32-bit depth, bilinear, exact perspective) and the terrain
//! default (RGB565, 16-bit depth, mipmapped bilinear, spans of 16) it prints the median frame
//! times and the median of the per-frame ratios (one thread's time over two threads').
//!
//! A third contender takes its turn too: two one-thread rasterizers drawing a frame each at the
//! same time, on two threads of their own. Nothing is shared between them but the machine, so
//! twice one thread's time over the pair's is what the machine gives two threads of this work:
//! the ceiling of the two-thread rasterizer's ratio.
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
    turns::header(scene::Scene::triangles(470), frames);
    for (name, color, depth, state) in s.both_states() {
        let mut fbs = [0; 4].map(|_| Framebuffer::new(1280, 720, color, depth).expect("valid"));
        let mut rs = [1, 2, 1, 1].map(Rasterizer::with_threads);
        let draw = |r: &mut Rasterizer, fb: &mut Framebuffer| {
            fb.clear([140, 180, 230]);
            r.draw(fb, &s.mesh(), &s.transform, &state)
                .expect("the scene is valid");
        };
        let turns = turns::take_turns::<3>(frames, |k| match k {
            0 | 1 => draw(&mut rs[k], &mut fbs[k]),
            _ => {
                let ([.., r2, r3], [.., fb2, fb3]) = (&mut rs, &mut fbs);
                std::thread::scope(|scope| {
                    scope.spawn(|| draw(r2, fb2));
                    draw(r3, fb3);
                });
            }
        });
        assert!(
            fbs.iter().all(|fb| *fb == fbs[0]),
            "one and two threads give the same bytes"
        );
        println!(
            "{name}: 1 thread {:.1} ms, 2 threads {:.1} ms, median ratio {:.2}; \
             two one-thread frames side by side {:.1} ms, ratio {:.2}",
            turns.median(0) * 1e3,
            turns.median(1) * 1e3,
            turns.ratio(0, 1),
            turns.median(2) * 1e3,
            2.0 * turns.ratio(0, 2),
        );
    }
}
