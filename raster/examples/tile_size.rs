//! What the screen tiles' size does: the peer benchmark's two scenes in size (A: 320x240, a
//! 72x72 grid of strips; B: 1280x720, 470x470) drawn in tiles of 64, 128, 256 and 512 pixels
//! (A's whole frame), on one thread and (B) on two, the four rasterizers of each case taking
//! turns frame by frame. Bigger tiles mean fewer triangles walked twice across a tile edge and
//! fewer tiles to load and store; smaller ones keep a tile in a nearer cache and give two
//! threads more tiles to share out. For the peers' state and the terrain default it prints, for each case, the median
//! frame times and the median per-frame ratio of 64's time to each size's (above 1: that size
//! is faster). The rasterizer's own choice is one tile where one thread draws a frame whose
//! colour and depth fit in 384 KiB (A in the terrain default), else 128, or 64 where that
//! leaves a thread fewer than eight tiles.
//!
//! ```sh
//! cargo run --release -p stripmask-raster --example tile_size -- 21
//! ```

#[path = "../tests/it/scene.rs"]
mod scene;
#[path = "support/turns.rs"]
mod turns;

use stripmask_raster::*;

/// The tile sides measured, in pixels.
const SIZES: [u32; 4] = [64, 128, 256, 512];

fn main() {
    let frames = turns::frames_arg("tile_size", 15);
    println!(
        "{frames} frames each at 1280x720, {} at 320x240, {} threads in the pool",
        frames * 20,
        rayon::current_num_threads()
    );
    // Scene A is far below the size a flush is split from: it is drawn on one thread only.
    for (grid, width, height, threads) in
        [(72, 320, 240, 1), (470, 1280, 720, 1), (470, 1280, 720, 2)]
    {
        let s = scene::terrain(grid, width, height);
        let frames = if grid == 72 { frames * 20 } else { frames };
        for (name, color, depth, state) in s.both_states() {
            let mut rs = SIZES.map(|side| Rasterizer::with_threads(threads).with_tile_size(side));
            let target = ((width, height), (color, depth));
            let turns = turns::draw_in_turns(&mut rs, &s, &state, target, frames, "tile size");
            print!("{width}x{height}, {threads} thread(s), {name}:");
            for (k, side) in SIZES.iter().enumerate() {
                print!(
                    "  {side}: {:.3} ms ({:.3})",
                    turns.median(k) * 1e3,
                    turns.ratio(0, k)
                );
            }
            println!();
        }
    }
}
