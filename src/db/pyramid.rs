//! The overview levels of the pyramid as a build makes them, streaming: each level's bands are
//! the level below's, every other row and column; a tile's texture is its four children's
//! next mips side by side; its errors are measured against the full-resolution samples it
//! stands for, through its children's.
//!
//! Heights are the level-0 samples themselves (every `2^k`-th), so a tile of any level stores,
//! for a sample it shares with a finer tile, the same integer height: where two levels meet,
//! their common border vertices are bit-identical.

use crate::db::level_error::level_errors;
use crate::db::mask_level::level_count;
use crate::db::rgb565::next_mip;
use crate::db::texture_gen::flat;
use crate::db::tiling::{Band, Tiling};

/// The tiling of every level of the pyramid over `level0`, level 0 first, up to one tile.
pub fn level_tilings(level0: Tiling) -> Vec<Tiling> {
    let mut tilings = vec![level0];
    while let Some(&t) = tilings.last().filter(|t| t.tiles_x > 1 || t.tiles_y > 1) {
        let (tiles_x, tiles_y) = (t.tiles_x.div_ceil(2), t.tiles_y.div_ceil(2));
        let cells = t.tile_size - 1;
        tilings.push(Tiling {
            tile_size: t.tile_size,
            tiles_x,
            tiles_y,
            width: tiles_x * cells + 1,
            height: tiles_y * cells + 1,
        });
    }
    tilings
}

/// What an encoded tile leaves for its parent: whether it is absent, its errors, and its
/// texture's next mip.
#[derive(Clone, Debug, PartialEq)]
pub struct ChildInfo {
    /// Every sample of it is nodata: nothing is stored.
    pub absent: bool,
    /// Its mask levels' errors against the full-resolution samples, metres.
    pub errors: Vec<f32>,
    /// Its texture's mip 1, 8-bit RGB, `t / 2` texels a side.
    pub texture: Vec<[u8; 3]>,
}

impl ChildInfo {
    /// What an absent tile of `s` samples whose (filled) heights are `heights` leaves: no
    /// error, a flat texture of the colour of its mean height (its parent draws the fill there).
    pub fn absent(heights: &[f32], s: usize, texture_size: usize) -> ChildInfo {
        let mean = heights.iter().map(|&h| f64::from(h)).sum::<f64>() / heights.len() as f64;
        let half = (texture_size / 2).max(1);
        ChildInfo {
            absent: true,
            errors: vec![0.0; level_count(s)],
            texture: vec![flat(mean as f32); half * half],
        }
    }

    /// What a present tile with `errors` and finest `texture` (`t x t`) leaves.
    pub fn present(errors: Vec<f32>, texture: &[[u8; 3]], texture_size: usize) -> ChildInfo {
        let texture = if texture_size > 1 {
            next_mip(texture, texture_size)
        } else {
            texture.to_vec()
        };
        ChildInfo {
            absent: false,
            errors,
            texture,
        }
    }
}

/// The errors of a tile whose own samples are `heights` (`s x s`) and whose present children
/// left `children`, against the full-resolution samples the tile stands for.
///
/// The tile's samples are every other sample of its children's, so its mask `l` drawn over a
/// child is that child's mask `2l + 1` whenever `l + 1` is a power of two that halves the
/// tile's side: that error is exact, the children's largest. Its other levels take the error
/// against the tile's own samples plus how far those stand from the full resolution (the
/// children's mask 1 error, exact): a bound, by the triangle inequality.
pub fn combined_errors(heights: &[f32], s: usize, children: &[&ChildInfo]) -> Vec<f32> {
    let own = level_errors(heights, s);
    let worst = |l: usize| {
        children
            .iter()
            .filter(|c| !c.absent)
            .map(|c| c.errors[l])
            .fold(0.0f32, f32::max)
    };
    let detail = worst(1.min(level_count(s) - 1));
    own.iter()
        .enumerate()
        .map(|(l, &e)| {
            let exact = (l + 1).is_power_of_two() && 2 * l + 1 < level_count(s);
            if exact { worst(2 * l + 1) } else { e + detail }
        })
        .collect()
}

/// The finest texture (`t x t`) of a tile whose children (north-west, north-east, south-west,
/// south-east; `None` beyond the grid) left theirs: the four next mips side by side. Where a
/// child lies beyond the grid, its neighbour's texels at the shared edge stand in for it, as
/// the padding repeats the last column and row of samples.
pub fn parent_texture(children: [Option<&ChildInfo>; 4], texture_size: usize) -> Vec<[u8; 3]> {
    let t = texture_size;
    let half = (t / 2).max(1);
    let mut out = Vec::with_capacity(t * t);
    for v in 0..t {
        for u in 0..t {
            let (mut cx, mut cy) = ((u / half).min(1), (v / half).min(1));
            let (mut x, mut y) = (u - cx * half, v - cy * half);
            if children[cy * 2 + cx].is_none() && cx == 1 {
                (cx, x) = (0, half - 1);
            }
            if children[cy * 2 + cx].is_none() && cy == 1 {
                (cy, y) = (0, half - 1);
            }
            let child = children[cy * 2 + cx].expect("the north-west child always exists");
            out.push(child.texture[y.min(half - 1) * half + x.min(half - 1)]);
        }
    }
    out
}

/// A band of a level above 0 put together from the level below's bands: band `b` of the
/// level below gives the upper half of this level's band `b / 2` when `b` is even, the lower
/// half when odd (the middle row comes from both, alike).
pub struct Assembly {
    tiling: Tiling,
    band: usize,
    samples: Vec<f32>,
    /// Rows written so far (0, half or all).
    rows: usize,
}

impl Assembly {
    /// The first band of the level tiled as `tiling`.
    pub fn new(tiling: Tiling) -> Assembly {
        Assembly {
            tiling,
            band: 0,
            samples: vec![0.0; tiling.padded_width() * tiling.tile_size],
            rows: 0,
        }
    }

    /// Takes in the level below's next band; returns this level's band once it is whole.
    pub fn add(&mut self, finer: &Band) -> Option<Band> {
        let s = self.tiling.tile_size;
        let half = (s - 1) / 2;
        let w = self.tiling.padded_width();
        let first = (finer.tile_row % 2) * half;
        debug_assert_eq!(finer.tile_row / 2, self.band);
        for j in 0..=half {
            let source = finer.row(2 * j);
            let row = &mut self.samples[(first + j) * w..(first + j + 1) * w];
            let kept = source.len().div_ceil(2);
            for (i, o) in row.iter_mut().enumerate() {
                *o = source[2 * i.min(kept - 1)];
            }
        }
        self.rows = first + half + 1;
        (self.rows == s).then(|| self.take())
    }

    /// The last band, its missing lower half repeating its last row (the grid's padding), if a
    /// band was begun and not handed out.
    pub fn finish(&mut self) -> Option<Band> {
        if self.rows == 0 {
            return None;
        }
        let (s, w) = (self.tiling.tile_size, self.tiling.padded_width());
        for j in self.rows..s {
            self.samples.copy_within((j - 1) * w..j * w, j * w);
        }
        Some(self.take())
    }

    fn take(&mut self) -> Band {
        let band = Band::new(self.band, self.tiling, self.samples.clone());
        self.band += 1;
        self.rows = 0;
        band
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::db::level_error::level_errors;

    /// A smooth bumpy surface of `n x n` samples.
    fn surface(n: usize) -> Vec<f32> {
        (0..n * n)
            .map(|k| {
                let (x, y) = ((k % n) as f32, (k / n) as f32);
                40.0 * (x * 0.37).sin() * (y * 0.21).cos() + 3.0 * ((x * y) * 0.05).sin()
            })
            .collect()
    }

    /// The `s x s` samples at every `step`-th sample from `(x0, y0)` of an `n`-wide grid.
    fn cut(grid: &[f32], n: usize, x0: usize, y0: usize, s: usize, step: usize) -> Vec<f32> {
        (0..s * s)
            .map(|k| grid[(y0 + (k / s) * step) * n + x0 + (k % s) * step])
            .collect()
    }

    /// The largest `|h - h_l|` over every sample of the `n x n` grid under the parent tile's
    /// mask `l` surface (the parent keeps every 2nd sample): the error by brute force.
    fn brute(grid: &[f32], n: usize, s: usize, l: usize) -> f32 {
        use crate::db::mask_level::kept_indices;
        let kept: Vec<usize> = kept_indices(s, l).into_iter().map(|i| 2 * i).collect();
        let h = |i: usize, j: usize| grid[j * n + i];
        let mut worst = 0.0f32;
        for cj in kept.windows(2) {
            for ci in kept.windows(2) {
                let (i0, i1, j0, j1) = (ci[0], ci[1], cj[0], cj[1]);
                for j in j0..=j1 {
                    for i in i0..=i1 {
                        let u = (i - i0) as f32 / (i1 - i0) as f32;
                        let v = (j - j0) as f32 / (j1 - j0) as f32;
                        let (h00, h10, h01, h11) = (h(i0, j0), h(i1, j0), h(i0, j1), h(i1, j1));
                        let p = if u >= v {
                            h00 + u * (h10 - h00) + v * (h11 - h10)
                        } else {
                            h00 + v * (h01 - h00) + u * (h11 - h01)
                        };
                        worst = worst.max((h(i, j) - p).abs());
                    }
                }
            }
        }
        worst
    }

    #[test]
    fn errors_are_exact_at_powers_of_two_and_bound_the_truth_elsewhere() {
        let s = 17;
        let n = 2 * (s - 1) + 1;
        let grid = surface(n);
        let children: Vec<ChildInfo> = [(0, 0), (16, 0), (0, 16), (16, 16)]
            .iter()
            .map(|&(x, y)| {
                let heights = cut(&grid, n, x, y, s, 1);
                ChildInfo::present(level_errors(&heights, s), &[[0; 3]; 4], 2)
            })
            .collect();
        let parent = cut(&grid, n, 0, 0, s, 2);
        let refs: Vec<&ChildInfo> = children.iter().collect();
        let errors = combined_errors(&parent, s, &refs);
        for (l, &e) in errors.iter().enumerate() {
            let truth = brute(&grid, n, s, l);
            if (l + 1).is_power_of_two() && 2 * l + 1 < s - 1 {
                assert!((e - truth).abs() < 1e-3, "level {l}: {e} against {truth}");
            } else {
                assert!(
                    e >= truth - 1e-3,
                    "level {l}: {e} is below the truth {truth}"
                );
            }
        }
        assert!(
            errors[0] > 0.0,
            "the parent's own samples miss the children's"
        );
    }

    #[test]
    fn absent_children_add_no_error() {
        let s = 9;
        let heights = surface(s);
        let present = ChildInfo::present(vec![5.0; s - 1], &[[0; 3]; 4], 2);
        let absent = ChildInfo::absent(&heights, s, 2);
        let with = combined_errors(&heights, s, &[&present, &absent]);
        let alone = combined_errors(&heights, s, &[&present]);
        assert_eq!(with, alone);
    }

    #[test]
    fn a_parent_texture_is_its_childrens_next_mips_side_by_side() {
        let child = |c: u8| ChildInfo {
            absent: false,
            errors: vec![],
            texture: (0..16).map(|k| [c, k as u8, 0]).collect(),
        };
        let (a, b, c, d) = (child(1), child(2), child(3), child(4));
        let t = parent_texture([Some(&a), Some(&b), Some(&c), Some(&d)], 8);
        assert_eq!(t[0], [1, 0, 0]);
        assert_eq!(t[4], [2, 0, 0]);
        assert_eq!(t[4 * 8 + 3], [3, 3, 0]);
        assert_eq!(t[7 * 8 + 7], [4, 15, 0]);
        // Beyond the grid to the east, the west child's last column stands in.
        let t = parent_texture([Some(&a), None, Some(&c), None], 8);
        assert_eq!(t[6], [1, 3, 0]);
        assert_eq!(t[5 * 8 + 7], [3, 7, 0]);
    }

    #[test]
    fn two_bands_below_make_one_band_of_every_other_sample() {
        let level0 = Tiling::new(17, 17, 5).unwrap();
        let tilings = level_tilings(level0);
        assert_eq!(
            tilings
                .iter()
                .map(|t| (t.tiles_x, t.tiles_y))
                .collect::<Vec<_>>(),
            [(4, 4), (2, 2), (1, 1)]
        );
        let (s, w) = (5, level0.padded_width());
        let band = |b: usize| {
            let samples = (0..s * w)
                .map(|k| ((b * 4 + k / w) * 100 + k % w) as f32)
                .collect();
            Band::new(b, level0, samples)
        };
        let mut up = Assembly::new(tilings[1]);
        assert!(up.add(&band(0)).is_none());
        let b = up.add(&band(1)).unwrap();
        assert_eq!(b.tile_row, 0);
        assert_eq!(b.row(0), [0.0, 2.0, 4.0, 6.0, 8.0, 10.0, 12.0, 14.0, 16.0]);
        assert_eq!(b.row(3)[..3], [600.0, 602.0, 604.0]);
        assert!(up.add(&band(2)).is_none());
        let last = up.finish().unwrap();
        assert_eq!((last.tile_row, last.row(4)[1]), (1, 1202.0));
        assert!(up.finish().is_none());
    }
}
