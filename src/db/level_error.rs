//! The geometric error of each strip-mask level against the full tile.
//!
//! The surface of level `l` is the triangulation of the samples that level keeps (see
//! [`crate::db::mask_level`]); every cell of the kept grid, from `(i0, j0)` to `(i1, j1)`, is split
//! along its main diagonal, from `(i0, j0)` to `(i1, j1)` (north-west to south-east). The error of
//! the level is the largest `|h - h_l|` over all samples of the tile, where `h_l` is the height
//! interpolated on the level's surface. Level 0 keeps every sample, so its error is 0.

use crate::db::mask_level::{kept_indices, level_count};

/// The maximum error of every mask level (`tile_size - 1` values, level 0 first) for a tile of
/// `tile_size x tile_size` heights, row-major.
///
/// Works cell by cell of each level's kept grid, so the inner loop runs over a contiguous part of
/// a row without branches (both triangles are evaluated and one is selected).
pub fn level_errors(heights: &[f32], tile_size: usize) -> Vec<f32> {
    let s = tile_size;
    debug_assert_eq!(heights.len(), s * s);
    let mut errors = Vec::with_capacity(level_count(s));
    errors.push(0.0);
    for level in 1..level_count(s) {
        let kept = kept_indices(s, level);
        let mut worst = 0.0f32;
        for cj in kept.windows(2) {
            let (j0, j1) = (cj[0], cj[1]);
            for ci in kept.windows(2) {
                let (i0, i1) = (ci[0], ci[1]);
                let h00 = heights[j0 * s + i0];
                let h10 = heights[j0 * s + i1];
                let h01 = heights[j1 * s + i0];
                let h11 = heights[j1 * s + i1];
                let inv_w = 1.0 / (i1 - i0) as f32;
                let inv_h = 1.0 / (j1 - j0) as f32;
                for j in j0..=j1 {
                    let v = (j - j0) as f32 * inv_h;
                    let row = &heights[j * s + i0..=j * s + i1];
                    for (di, &h) in row.iter().enumerate() {
                        let u = di as f32 * inv_w;
                        // North-east triangle (00, 10, 11) when u >= v, else south-west (00, 01, 11).
                        let upper = h00 + u * (h10 - h00) + v * (h11 - h10);
                        let lower = h00 + v * (h01 - h00) + u * (h11 - h01);
                        let interpolated = if u >= v { upper } else { lower };
                        let e = (h - interpolated).abs();
                        if e > worst {
                            worst = e;
                        }
                    }
                }
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
