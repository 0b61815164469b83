//! What the thread examples share: their frame-count argument, and rasterizers drawing the same
//! frame in turns, so that a shared machine's load falls on all of them alike.

#![allow(dead_code)] // each including example uses a different part

use std::time::Instant;

use stripmask_raster::{ColorFormat, DepthFormat, Framebuffer, Rasterizer, RenderState};

use super::scene::Scene;

/// The frame count, the first argument (`default` without one); exits with status 2 when it is
/// not a positive number.
pub fn frames_arg(example: &str, default: usize) -> usize {
    match std::env::args().nth(1).map(|a| a.parse()) {
        None => default,
        Some(Ok(n)) if n > 0 => n,
        _ => {
            eprintln!("{example}: the frame count must be a positive number");
            std::process::exit(2);
        }
    }
}

/// Says what a thread example draws: `triangles` at 1280x720 (scene B of the peer benchmark in
/// size), `frames` frames each, and the threads of the pool.
pub fn header(triangles: u64, frames: usize) {
    println!(
        "{triangles} triangles at 1280x720, {frames} frames each, {} threads in the pool",
        rayon::current_num_threads()
    );
}

/// The median of `v` (reordered).
pub fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The frame times of contenders that took turns: one row of times in seconds per frame.
pub struct Turns<const N: usize> {
    frames: Vec<[f64; N]>,
}

impl<const N: usize> Turns<N> {
    /// The median frame time of contender `k`, in seconds.
    pub fn median(&self, k: usize) -> f64 {
        median(&mut self.frames.iter().map(|t| t[k]).collect::<Vec<_>>())
    }

    /// The median of the per-frame ratios of contender `a`'s time to contender `b`'s.
    pub fn ratio(&self, a: usize, b: usize) -> f64 {
        median(&mut self.frames.iter().map(|t| t[a] / t[b]).collect::<Vec<_>>())
    }
}

/// Times `frames` frames of `draw(0)` to `draw(N - 1)`, each frame started by the next in turn,
/// after one uncounted frame of each (it sizes the scratch buffers).
pub fn take_turns<const N: usize>(frames: usize, mut draw: impl FnMut(usize)) -> Turns<N> {
    let mut times = Vec::with_capacity(frames);
    for f in 0..frames + 1 {
        let mut t = [0.0; N];
        for k in (0..N).map(|i| (f + i) % N) {
            let start = Instant::now();
            draw(k);
            t[k] = start.elapsed().as_secs_f64();
        }
        if f > 0 {
            times.push(t);
        }
    }
    Turns { frames: times }
}

/// Times `frames` frames of scene `s` in `state`, drawn by each of `rs` in turn into a
/// framebuffer of its own (`size`, `formats`), and asserts that they all drew the same bytes
/// (`what` says what differs between them).
pub fn draw_in_turns<const N: usize>(
    rs: &mut [Rasterizer; N],
    s: &Scene,
    state: &RenderState,
    (size, formats): ((u32, u32), (ColorFormat, DepthFormat)),
    frames: usize,
    what: &str,
) -> Turns<N> {
    let mut fbs = [0; N].map(|_| {
        Framebuffer::new(size.0, size.1, formats.0, formats.1).expect("the target is valid")
    });
    let turns = take_turns::<N>(frames, |k| {
        fbs[k].clear([140, 180, 230]);
        rs[k]
            .draw(&mut fbs[k], &s.mesh(), &s.transform, state)
            .expect("the scene is valid");
    });
    assert!(
        fbs.iter().all(|fb| *fb == fbs[0]),
        "every {what} gives the same bytes"
    );
    turns
}
