//! What the thread examples share: their frame-count argument, and a one-thread and a
//! two-thread rasterizer drawing the same frame in turns, so that a shared machine's load falls
//! on both alike.

use std::time::Instant;

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

/// The median of `v` (reordered).
pub fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Times `frames` frames of `draw(0)` and `draw(1)` taking turns to go first, after one
/// uncounted frame of each (it sizes the scratch buffers). Returns both median frame times in
/// seconds and the median of the per-frame ratios (`draw(0)`'s time over `draw(1)`'s).
pub fn take_turns(frames: usize, mut draw: impl FnMut(usize)) -> ([f64; 2], f64) {
    let (mut times, mut ratios) = ([Vec::new(), Vec::new()], Vec::new());
    for f in 0..frames + 1 {
        let mut t = [0.0; 2];
        for k in [f % 2, 1 - f % 2] {
            let start = Instant::now();
            draw(k);
            t[k] = start.elapsed().as_secs_f64();
        }
        if f > 0 {
            times[0].push(t[0]);
            times[1].push(t[1]);
            ratios.push(t[0] / t[1]);
        }
    }
    let [one, two] = &mut times;
    ([median(one), median(two)], median(&mut ratios))
}
