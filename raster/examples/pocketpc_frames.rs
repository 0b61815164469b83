//! Draws the benchmark's PocketPC frame (320x240 RGB565 + 16-bit depth, 10,082 textured,
//! shaded, depth-tested strip triangles, one thread) a number of times and prints the median
//! frame time and a checksum of the pixels: a small, steady driver for instruction counts, where
//! the shared machine makes wall-clock medians noisy, and a quick check that a change kept every
//! pixel. With `--peers` it draws the same triangles in the peers' state (RGBA8888, 32-bit depth,
//! bilinear without mipmaps, exact perspective), the state the peer benchmark compares. With
//! `--grid N` the terrain is an N x N grid of quads instead of 72 x 72: at 34 it has 2,178
//! triangles over the same pixels, the few larger triangles of the engine's own PocketPC frames
//! (about 2,600), which take the general row step rather than the small-triangle loop. With
//! `--big` it draws scene B of the peer benchmark instead: 1280x720, a 470 x 470 grid (439,922
//! triangles), far terrain as slivers. With `--size WxH` it draws the same scene into a
//! framebuffer of that size (`--size 800x480`: the LCD of today's 32-bit boards). With
//! `--baseline` its hot loops keep to the build target's baseline instructions
//! (`InstructionSet::Baseline`) even where the CPU has AVX2.
//!
//! ```sh
//! cargo build --release -p stripmask-raster --example pocketpc_frames
//! valgrind --tool=callgrind target/release/examples/pocketpc_frames 10
//! valgrind --tool=callgrind target/release/examples/pocketpc_frames 10 --peers
//! valgrind --tool=callgrind target/release/examples/pocketpc_frames 10 --grid 34
//! valgrind --tool=callgrind target/release/examples/pocketpc_frames 10 --baseline
//! valgrind --tool=callgrind target/release/examples/pocketpc_frames 10 --size 800x480
//! target/release/examples/pocketpc_frames 2000
//! valgrind --tool=callgrind target/release/examples/pocketpc_frames 4 --big
//! ```

#[path = "../tests/it/scene.rs"]
mod scene;

use stripmask_raster::*;

fn main() {
    let number = |what: &str, v: Option<String>| -> u32 {
        match v.as_deref().map(str::parse) {
            Some(Ok(n)) => n,
            _ => {
                eprintln!("pocketpc_frames: {what} must be a number (got {v:?})");
                std::process::exit(2);
            }
        }
    };
    let mut args = std::env::args().skip(1);
    let (mut peers, mut grid, mut frames) = (false, 72, 10);
    let mut size = (320, 240);
    let mut set = InstructionSet::Detected;
    while let Some(a) = args.next() {
        match a.as_str() {
            "--peers" => peers = true,
            "--baseline" => set = InstructionSet::Baseline,
            "--big" => (grid, size) = (470, (1280, 720)),
            "--grid" => grid = number("the grid size after --grid", args.next()).max(1),
            "--size" => {
                let v = args.next();
                let wh = v.as_deref().and_then(|v| v.split_once('x'));
                let side =
                    |s: Option<&str>| number("the size after --size (WxH)", s.map(str::to_owned));
                size = (side(wh.map(|p| p.0)), side(wh.map(|p| p.1)));
            }
            _ => frames = number("the frame count", Some(a)),
        }
    }
    let s = scene::terrain(grid, size.0, size.1);
    let [peers_case, default_case] = s.both_states();
    let (_, color, depth, state) = if peers { peers_case } else { default_case };
    let mut fb = Framebuffer::new(size.0, size.1, color, depth).expect("the target is valid");
    let mut r = Rasterizer::with_threads(1).with_instruction_set(set);
    let mut stats = DrawStats::default();
    let mut times = Vec::with_capacity(frames as usize);
    for _ in 0..frames {
        let t = std::time::Instant::now();
        fb.clear([150, 180, 220]);
        stats = r
            .draw(&mut fb, &s.mesh(), &s.transform, &state)
            .expect("the scene is valid");
        times.push(t.elapsed());
    }
    times.sort();
    let median = times.get(times.len() / 2).copied().unwrap_or_default();
    // FNV-1a over the colour buffer: equal pictures print equal sums.
    let image = fb.to_rgba_image();
    let sum = image
        .as_raw()
        .iter()
        .fold(0xcbf2_9ce4_8422_2325u64, |h, &b| {
            (h ^ b as u64).wrapping_mul(0x100_0000_01b3)
        });
    println!(
        "{frames} frames, median {:.3} ms, {} triangles, {} rasterized, {} fragments, picture {sum:016x}",
        median.as_secs_f64() * 1e3,
        stats.triangles,
        stats.rasterized,
        stats.fragments
    );
}
