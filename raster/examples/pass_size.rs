//! What the size of a flush's passes does to one big draw: scene B in size (1280x720, a 470x470
//! grid of strips, 439,922 triangles) drawn in passes of 16k, 32k, 64k (the default) and 128k
//! triangles, each on one and on two threads, all eight rasterizers taking turns frame by frame.
//! A pass ends when its last tile is drawn, so on two threads each pass ends with one thread
//! waiting for the other; bigger passes wait fewer times but hold more set-up data. For the
//! peers' state and the terrain default it prints, for each size, the median frame times, the
//! median per-frame ratio of one thread's time to two threads', and two threads' time at the
//! default size over theirs at this size (above 1: this size is faster).
//!
//! ```sh
//! cargo run --release -p stripmask-raster --example pass_size -- 21
//! ```

#[path = "../tests/it/scene.rs"]
mod scene;
#[path = "support/turns.rs"]
mod turns;

use stripmask_raster::*;

/// The pass sizes measured, in triangles; `DEFAULT` indexes the rasterizer's own.
const SIZES: [usize; 4] = [16 << 10, 32 << 10, 64 << 10, 128 << 10];
const DEFAULT: usize = 2;

fn main() {
    let frames = turns::frames_arg("pass_size", 15);
    let s = scene::terrain(470, 1280, 720);
    turns::header(scene::Scene::triangles(470), frames);
    for (name, color, depth, state) in s.both_states() {
        // Contender `2 * i + t` draws with passes of `SIZES[i]` on `t + 1` threads.
        let mut rs: [Rasterizer; 2 * SIZES.len()] = std::array::from_fn(|k| {
            Rasterizer::with_threads(k % 2 + 1).with_pass_triangles(SIZES[k / 2])
        });
        let target = ((1280, 720), (color, depth));
        let turns = turns::draw_in_turns(
            &mut rs,
            &s,
            &state,
            target,
            frames,
            "pass size and thread count",
        );
        println!("{name}:");
        for (i, size) in SIZES.iter().enumerate() {
            let (one, two) = (2 * i, 2 * i + 1);
            println!(
                "  passes of {:>3}k: 1 thread {:.1} ms, 2 threads {:.1} ms, ratio {:.2}; \
                 2 threads at {}k over this {:.2}",
                size >> 10,
                turns.median(one) * 1e3,
                turns.median(two) * 1e3,
                turns.ratio(one, two),
                SIZES[DEFAULT] >> 10,
                turns.ratio(2 * DEFAULT + 1, two),
            );
        }
    }
}
