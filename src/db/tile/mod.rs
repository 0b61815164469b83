//! One tile: what the runtime needs for it and nothing more, whole or as the coarser tile that
//! a prefix of its progressive levels makes. The stored form is in `payload`: one chunk per
//! progressive level, coarse first.
//!
//! Quantisation is global: every tile of an archive counts heights in the same `quantum`, and a
//! sample's archive-wide integer height is `base + q`. The same DEM sample therefore gets the same
//! integer in both tiles that share it, which is what lets the engine draw neighbouring tiles
//! without a crack. A decoded height is within `quantum / 2` of the true one; a tile's relief must
//! fit 65535 quanta.

mod apron;
mod payload;

pub use apron::{Apron, Border};
pub use payload::level_payload_size;

use std::ops::Range;

use crate::db::level_error::level_errors;
use crate::db::rgb565::{mip_chain, mip_count};

/// The largest texture side a tile may carry.
pub const MAX_TEXTURE_SIZE: usize = 4096;

/// The progressive levels of a tile of `tile_size = 2^n + 1` samples per side: `n + 1`. Level
/// `g` is the grid of `2^g + 1` samples per side that keeps every `2^(n - g)`-th sample; level 0
/// is the four corners, level `n` the whole tile. Each level adds only the samples the coarser
/// ones lack, so a tile holding levels `0..k` is a usable coarser tile.
pub fn progressive_levels(tile_size: usize) -> usize {
    (tile_size.max(2) - 1).ilog2() as usize + 1
}

/// The progressive levels (of `levels` in all) a tile needs to draw mask `level`: a mask keeping
/// every `l + 1`-th sample needs the grid whose spacing divides `l + 1`. That grid is also the
/// one a tile drawn at mask `level` is lit from, whole or partial.
pub fn levels_for_mask(level: usize, levels: usize) -> usize {
    let spacing_log2 = (level + 1).trailing_zeros() as usize;
    levels - spacing_log2.min(levels - 1)
}

/// The finest mask level a tile holding `held` of its `levels` progressive levels draws: every
/// `2^(levels - held)`-th sample (the inverse of [`levels_for_mask`]).
pub fn finest_mask_for_levels(held: usize, levels: usize) -> usize {
    (1 << levels.saturating_sub(held.max(1))) - 1
}

/// Samples per side of progressive level `level`'s grid: `2^level + 1`.
pub fn level_side(level: usize) -> usize {
    (1 << level) + 1
}

/// The texture mips (indices into the archive's chain, 0 the finest) that progressive level
/// `level` carries: the mip a tile drawn at that level's sample spacing reads (mip `n - level`,
/// clamped to the chain), and for level 0 every coarser one too. Levels whose mip a coarser level
/// already carries carry none; every mip is carried by exactly one level.
pub fn level_mips(level: usize, tile_size: usize, texture_size: usize) -> Range<usize> {
    let n = progressive_levels(tile_size) - 1;
    let last = mip_count(texture_size) - 1;
    let shown = |g: usize| (n - g).min(last);
    if level == 0 {
        shown(0)..last + 1
    } else {
        shown(level)..shown(level - 1)
    }
}

/// The texture coordinate (0 ..= 1, across or down) of the point `x` whole-tile samples from a
/// tile's western (or northern) border, for a tile of `tile_size` samples whose finest texture
/// is `texture_size` texels wide. Texel `u` shows the point `u (s - 1) / (t - 1)` samples from the
/// border, so the border falls on the centre of the edge texel, which both tiles sharing the
/// border hold alike: bilinear sampling is as continuous across the border as inside the tile.
pub fn texture_coordinate(x: usize, tile_size: usize, texture_size: usize) -> f32 {
    texture_coordinate_at(x as f64, tile_size, texture_size)
}

/// [`texture_coordinate`] of a point `x` samples from the border that may lie between samples
/// (a vertex of an overview tile moved onto the model's last sample).
pub fn texture_coordinate_at(x: f64, tile_size: usize, texture_size: usize) -> f32 {
    let span = (texture_size.max(2) - 1) as f64 / (tile_size - 1) as f64;
    ((0.5 + x * span) / texture_size as f64) as f32
}

/// What a tile holding a prefix of its progressive levels knows of the grid it holds: shared by
/// the decoded [`Tile`] and the resident form.
pub trait PartialGrid {
    /// Samples per side of the whole tile.
    fn whole_size(&self) -> usize;
    /// Progressive levels held, at least 1.
    fn held_levels(&self) -> usize;

    /// Samples per side of the held grid: `2^(levels - 1) + 1`.
    fn side(&self) -> usize {
        level_side(self.held_levels() - 1)
    }

    /// Whole-tile samples between neighbouring samples of the held grid.
    fn stride(&self) -> usize {
        (self.whole_size() - 1) / (self.side() - 1)
    }

    /// Whether every progressive level is held.
    fn is_complete(&self) -> bool {
        self.held_levels() == progressive_levels(self.whole_size())
    }

    /// The finest strip-mask level the held samples can draw: a mask keeping every
    /// `stride`-th sample.
    fn finest_mask_level(&self) -> usize {
        finest_mask_for_levels(self.held_levels(), progressive_levels(self.whole_size()))
    }
}

impl PartialGrid for Tile {
    fn whole_size(&self) -> usize {
        self.tile_size
    }

    fn held_levels(&self) -> usize {
        self.levels
    }
}

/// One decoded tile, or the coarser tile that a prefix of its progressive levels makes.
#[derive(Clone, Debug, PartialEq)]
pub struct Tile {
    /// Samples per side of the whole tile.
    pub tile_size: usize,
    /// Progressive levels held, `1 ..= progressive_levels(tile_size)`: the held grid is
    /// [`Tile::side`] samples per side, every [`Tile::stride`]-th sample of the whole tile.
    pub levels: usize,
    /// Lowest height in metres.
    pub min: f32,
    /// Highest height in metres.
    pub max: f32,
    /// The tile's quantum 0 in archive quanta: sample `(i, j)` is `base + heights[j * s + i]`.
    pub base: i32,
    /// Metres per quantum.
    pub quantum: f32,
    /// Maximum geometric error of each mask level against the full tile, metres, level 0 first.
    pub level_errors: Vec<f32>,
    /// Quantised heights of the held grid, `side^2`, row-major from the north-west.
    pub heights: Vec<u16>,
    /// Texture side in texels of the archive's finest mip.
    pub texture_size: usize,
    /// Which mip of the archive's chain `texture_mips[0]` is (0 for a whole tile).
    pub first_mip: usize,
    /// RGB565 mip chain from mip `first_mip`, finest first, down to 1 x 1.
    pub texture_mips: Vec<Vec<u16>>,
    /// The samples just outside the borders of each held level, so that normals at the border
    /// are central differences like everywhere else.
    pub apron: Apron,
}

impl Tile {
    /// Builds a tile from `s x s` heights in metres, quantised in steps of `quantum` metres, and
    /// its finest texture (RGB, side `t`). Fails when the tile's relief exceeds 65535 quanta or a
    /// height is beyond ±2^31 quanta.
    pub fn new(
        heights: &[f32],
        tile_size: usize,
        quantum: f32,
        texture: &[[u8; 3]],
        texture_size: usize,
    ) -> std::result::Result<Tile, String> {
        if !(quantum.is_finite() && quantum > 0.0) {
            return Err(format!("height quantum {quantum} is not a positive number"));
        }
        let (min, max) = heights
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &h| {
                (lo.min(h), hi.max(h))
            });
        let step = f64::from(quantum);
        let to_quanta = |h: f32| (f64::from(h) / step).round();
        let (lo, hi) = (to_quanta(min), to_quanta(max));
        if !(lo >= f64::from(i32::MIN) && hi <= f64::from(i32::MAX)) {
            return Err(format!(
                "heights {min} ..= {max} m are beyond ±2^31 quanta of {quantum} m"
            ));
        }
        if hi - lo > f64::from(u16::MAX) {
            return Err(format!(
                "the tile spans {min} ..= {max} m, more than 65535 quanta of {quantum} m: \
                 choose a larger height quantum"
            ));
        }
        let base = lo as i32;
        let quantised = heights
            .iter()
            .map(|&h| (to_quanta(h) - lo) as u16)
            .collect();
        let tile = Tile {
            tile_size,
            levels: progressive_levels(tile_size),
            min,
            max,
            base,
            quantum,
            level_errors: level_errors(heights, tile_size),
            heights: quantised,
            texture_size,
            first_mip: 0,
            texture_mips: mip_chain(texture, texture_size),
            apron: Apron::default(),
        };
        Ok(tile.with_apron(|_, _| None))
    }

    /// The whole tile with its apron taken from `outside(x, y)`: the height in metres of the
    /// sample `(x, y)` whole-tile steps from the tile's north-west sample (one of them outside
    /// `0 ..= s - 1`), or `None` beyond the archive's grid, where the border is extrapolated
    /// linearly (so the normal there is the one-sided difference of a tile on its own).
    pub fn with_apron(mut self, outside: impl Fn(isize, isize) -> Option<f32>) -> Tile {
        debug_assert!(self.is_complete(), "the apron is built from a whole tile");
        let n = self.levels - 1;
        let step = f64::from(self.quantum);
        let sides: Vec<usize> = (0..self.levels).map(level_side).collect();
        let apron = Apron::from_fn(&sides, |g, border, k| {
            let stride = 1isize << (n - g);
            let ((ox, oy), (ix, iy)) = border.positions(k, sides[g]);
            let at = |x: usize, y: usize| i64::from(self.quanta(x, y));
            let inside = at(ix * stride as usize, iy * stride as usize);
            let q = match outside(ox * stride, oy * stride) {
                Some(h) => (f64::from(h) / step).round() as i64,
                None => {
                    // The next sample inwards mirrors the outside one about the border.
                    let x = (2 * ix as isize - ox) * stride;
                    let y = (2 * iy as isize - oy) * stride;
                    2 * inside - at(x as usize, y as usize)
                }
            };
            apron::saturating_delta(q, inside)
        });
        self.apron = apron;
        self
    }

    /// The coarser tile that the first `levels` progressive levels make (clamped to
    /// `1 ..= self.levels`): every `2^k`-th held sample and the texture mips those levels carry.
    pub fn truncated(&self, levels: usize) -> Tile {
        let levels = levels.clamp(1, self.levels);
        let step = 1 << (self.levels - levels);
        let side = level_side(levels - 1);
        let heights = (0..side * side)
            .map(|k| self.heights[(k / side) * step * self.side() + (k % side) * step])
            .collect();
        let first_mip = level_mips(levels - 1, self.tile_size, self.texture_size)
            .start
            .max(self.first_mip);
        Tile {
            levels,
            heights,
            first_mip,
            texture_mips: self.texture_mips[first_mip - self.first_mip..].to_vec(),
            level_errors: self.level_errors.clone(),
            apron: self.apron.truncated(levels),
            ..*self
        }
    }

    /// The archive-wide integer height of held-grid sample `(i, j)`, in quanta (whole-tile
    /// sample `(i * stride, j * stride)`).
    pub fn quanta(&self, i: usize, j: usize) -> i32 {
        self.base + i32::from(self.heights[j * self.side() + i])
    }

    /// Row `j` of [`Tile::quanta`], west to east: one walk of a slice instead of an index
    /// product per sample.
    pub fn quanta_row(&self, j: usize) -> impl Iterator<Item = i32> + '_ {
        let side = self.side();
        self.heights[j * side..(j + 1) * side]
            .iter()
            .map(|&h| self.base + i32::from(h))
    }

    /// The archive-wide height in quanta of position `(i, j)` of held progressive level
    /// `level`'s grid (every `2^(levels - 1 - level)`-th held sample), inside that grid or one
    /// step outside one of its borders (from that level's apron; not diagonally outside a
    /// corner).
    pub fn quanta_around(&self, level: usize, i: isize, j: isize) -> i64 {
        debug_assert!(level < self.levels);
        let step = 1usize << (self.levels - 1 - level);
        let last = level_side(level) as isize - 1;
        let inside =
            |x: isize, y: isize| i64::from(self.quanta(x as usize * step, y as usize * step));
        let apron = |border: Border, k: isize, x: isize, y: isize| {
            inside(x, y) + i64::from(self.apron.delta(level, border, k as usize))
        };
        match (i, j) {
            (-1, _) => apron(Border::West, j, 0, j),
            (_, -1) => apron(Border::North, i, i, 0),
            (x, _) if x > last => apron(Border::East, j, last, j),
            (_, y) if y > last => apron(Border::South, i, i, last),
            _ => inside(i, j),
        }
    }

    /// The height in metres of held-grid sample `(i, j)`.
    pub fn height(&self, i: usize, j: usize) -> f32 {
        (f64::from(self.quanta(i, j)) * f64::from(self.quantum)) as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_nest_and_carry_every_mip_once() {
        assert_eq!(progressive_levels(3), 2);
        assert_eq!(progressive_levels(65), 7);
        assert_eq!(level_side(0), 2);
        assert_eq!(level_side(6), 65);
        // s = 9 (levels 0..=3) with a 32-texel chain (mips 0..=5): level 0 carries 5, 4, 3.
        let carried: Vec<_> = (0..4).map(|g| level_mips(g, 9, 32)).collect();
        assert_eq!(carried, [3..6, 2..3, 1..2, 0..1]);
        // s = 65 (levels 0..=6) with a 16-texel chain (mips 0..=4): levels 1 and 2 carry none.
        let carried: Vec<_> = (0..7).map(|g| level_mips(g, 65, 16)).collect();
        assert_eq!(carried, [4..5, 4..4, 4..4, 3..4, 2..3, 1..2, 0..1]);
    }

    #[test]
    fn a_truncated_tile_keeps_the_coarser_grid_and_mips() {
        let s = 9;
        let heights: Vec<f32> = (0..s * s).map(|k| k as f32).collect();
        let tile = Tile::new(&heights, s, 1.0, &[[1, 2, 3]; 64], 8).unwrap();
        assert_eq!((tile.side(), tile.stride(), tile.levels), (9, 1, 4));
        let coarse = tile.truncated(2);
        assert_eq!((coarse.side(), coarse.stride()), (3, 4));
        assert_eq!(coarse.finest_mask_level(), 3);
        assert_eq!(coarse.quanta(1, 2), tile.quanta(4, 8));
        assert_eq!(coarse.first_mip, 2);
        assert_eq!(coarse.texture_mips[..], tile.texture_mips[2..]);
        assert_eq!(coarse.truncated(1), tile.truncated(1));
        assert_eq!(tile.truncated(1).heights.len(), 4);
        assert!(!coarse.is_complete() && tile.is_complete());
    }

    #[test]
    fn rows_of_quanta_are_the_samples_quanta() {
        let s = 9;
        let heights: Vec<f32> = (0..s * s).map(|k| (k * 7 % 23) as f32).collect();
        let tile = Tile::new(&heights, s, 0.5, &[[1, 2, 3]; 64], 8).unwrap();
        for t in [tile.truncated(2), tile.truncated(3), tile] {
            for j in 0..t.side() {
                let row: Vec<i32> = t.quanta_row(j).collect();
                let each: Vec<i32> = (0..t.side()).map(|i| t.quanta(i, j)).collect();
                assert_eq!(row, each, "row {j} of a tile of side {}", t.side());
            }
        }
    }

    #[test]
    fn relief_beyond_65535_quanta_is_refused_with_the_reason() {
        let texture = vec![[0, 0, 0]; 4];
        let heights = [0.0, 0.0, 0.0, 4096.0];
        let err = Tile::new(&heights, 2, 0.0625, &texture, 2).unwrap_err();
        assert!(err.contains("65535 quanta"), "{err}");
        assert!(Tile::new(&heights, 2, 0.125, &texture, 2).is_ok());
        assert!(Tile::new(&heights, 2, 0.0, &texture, 2).is_err());
    }
}
