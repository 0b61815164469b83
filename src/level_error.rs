//! The geometric error of each strip-mask level against the full tile.
//!
//! The surface of level `l` is the triangulation of the samples that level keeps (see
//! [`crate::mask_level`]); every cell of the kept grid, from `(i0, j0)` to `(i1, j1)`, is split
//! along its main diagonal, from `(i0, j0)` to `(i1, j1)` (north-west to south-east). The error of
//! the level is the largest `|h - h_l|` over all samples of the tile, where `h_l` is the height
//! interpolated on the level's surface. Level 0 keeps every sample, so its error is 0.

use crate::mask_level::{kept_indices, level_count};

/// For each grid index, the kept indices `(a, b)` around it (`a <= i <= b`).
fn brackets(tile_size: usize, level: usize) -> Vec<(usize, usize)> {
    let kept = kept_indices(tile_size, level);
    let mut out = Vec::with_capacity(tile_size);
    let mut k = 0;
    for i in 0..tile_size {
        while k + 1 < kept.len() && kept[k + 1] <= i {
            k += 1;
        }
        let a = kept[k];
        let b = if a == i { i } else { kept[k + 1] };
        out.push((a, b));
    }
    out
}

/// The maximum error of every mask level (`tile_size - 1` values, level 0 first) for a tile of
/// `tile_size x tile_size` heights, row-major.
pub fn level_errors(heights: &[f32], tile_size: usize) -> Vec<f32> {
    let s = tile_size;
    debug_assert_eq!(heights.len(), s * s);
    let h = |i: usize, j: usize| heights[j * s + i];
    let mut errors = Vec::with_capacity(level_count(s));
    errors.push(0.0);
    for level in 1..level_count(s) {
        let br = brackets(s, level);
        let mut worst = 0.0f32;
        for (j, &(j0, j1)) in br.iter().enumerate() {
            let v = if j1 > j0 {
                (j - j0) as f32 / (j1 - j0) as f32
            } else {
                0.0
            };
            for (i, &(i0, i1)) in br.iter().enumerate() {
                if i0 == i1 && j0 == j1 {
                    continue;
                }
                let u = if i1 > i0 {
                    (i - i0) as f32 / (i1 - i0) as f32
                } else {
                    0.0
                };
                let h00 = h(i0, j0);
                let h11 = h(i1, j1);
                let interpolated = if u >= v {
                    let h10 = h(i1, j0);
                    h00 + u * (h10 - h00) + v * (h11 - h10)
                } else {
                    let h01 = h(i0, j1);
                    h00 + v * (h01 - h00) + u * (h11 - h01)
                };
                worst = worst.max((h(i, j) - interpolated).abs());
            }
        }
        errors.push(worst);
    }
    errors
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_plane_has_no_error_at_any_level() {
        let s = 17;
        let heights: Vec<f32> = (0..s * s)
            .map(|k| 3.0 * (k % s) as f32 - 2.0 * (k / s) as f32 + 5.0)
            .collect();
        for e in level_errors(&heights, s) {
            assert!(e < 1e-4, "{e}");
        }
    }

    #[test]
    fn a_single_spike_is_seen_by_every_level_that_drops_it() {
        let s = 9;
        let mut heights = vec![0.0; s * s];
        heights[3 * s + 3] = 10.0;
        let e = level_errors(&heights, s);
        assert_eq!(e.len(), 8);
        assert_eq!(e[0], 0.0);
        // Level 1 drops the spike; level 2 keeps it (3 is a multiple of 3) but its neighbours
        // are interpolated towards it; level 3 drops it again.
        assert_eq!(e[1], 10.0);
        assert!((e[2] - 20.0 / 3.0).abs() < 1e-4, "{}", e[2]);
        assert_eq!(e[3], 10.0);
    }
}
