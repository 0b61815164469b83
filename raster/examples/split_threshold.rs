//! Where a second thread starts to pay: the terrain scene at grid sizes from a few hundred to
//! some forty thousand triangles, in one draw, at the handheld's 320x240 (RGB565, 16-bit depth)
//! and the workstation's 1280x720 (RGBA8888, 32-bit depth), with the terrain default state. A
//! one-thread rasterizer and a two-thread one that splits every flush take turns frame by
//! frame; for each size it prints the median frame times and the median of the per-frame ratios
//! (one thread's time over two threads': above 1, the second thread pays). The rasterizer's
//! default split point, below which a flush stays on the calling thread, comes from this table.
//!
//! ```sh
//! cargo run --release -p stripmask-raster --example split_threshold -- 201
//! ```

#[path = "../tests/it/scene.rs"]
mod scene;
#[path = "support/turns.rs"]
mod turns;

use stripmask_raster::*;

fn main() {
    let frames = turns::frames_arg("split_threshold", 101);
    println!(
        "{frames} frames each, {} threads in the pool",
        rayon::current_num_threads()
    );
    let screens = [
        (320, 240, ColorFormat::Rgb565, DepthFormat::D16),
        (1280, 720, ColorFormat::Rgba8888, DepthFormat::D32),
    ];
    for (width, height, color, depth) in screens {
        println!("{width}x{height}:");
        for grid in [12, 17, 24, 34, 41, 48, 58, 68, 96, 136] {
            let s = scene::terrain(grid, width, height);
            let state = s.state();
            let mut fbs = [1, 2].map(|_| Framebuffer::new(width, height, color, depth).unwrap());
            let mut rs = [
                Rasterizer::with_threads(1),
                Rasterizer::with_threads(2).with_split_from(0),
            ];
            let mut stats = DrawStats::default();
            let turns = turns::take_turns::<2>(frames, |k| {
                fbs[k].clear([140, 180, 230]);
                stats = rs[k]
                    .draw(&mut fbs[k], &s.mesh(), &s.transform, &state)
                    .expect("the scene is valid");
            });
            assert!(fbs[0] == fbs[1], "one and two threads give the same bytes");
            println!(
                "  {:>6} triangles, {:>7} pixels: 1 thread {:.3} ms, 2 threads {:.3} ms, median ratio {:.2}",
                stats.triangles,
                stats.fragments,
                turns.median(0) * 1e3,
                turns.median(1) * 1e3,
                turns.ratio(0, 1),
            );
        }
    }
}
