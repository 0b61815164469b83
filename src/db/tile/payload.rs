//! The progressive tile payload: one raw chunk per progressive level, coarse first, so that any
//! prefix of the chunks decodes to a usable coarser tile and no sample is stored twice.
//!
//! Layout of each chunk before compression (all little-endian), for a tile of `s` samples per
//! side and a texture of side `t`:
//!
//! * chunk 0: `min` f32, `max` f32, `base` i32, `quantum` f32, `level_errors` (`s - 1` x f32),
//!   the four corner heights `q` u16 (NW, NE, SW, SE), level 0's apron ([`Apron`]: 4 x 2 i16),
//!   then the texture mips [`level_mips`]`(0, s, t)`, smallest first, each row-major RGB565 u16.
//! * chunk `g >= 1`: the samples of level `g`'s grid that level `g - 1` lacks (an odd column or
//!   row), row-major over level `g`'s grid, each a u16 prediction residual `q - p` (wrapping),
//!   where `p` is the floor of the mean of the two level-`(g - 1)` neighbours (a sample between
//!   two along a row or a column) or of the four diagonal ones (a cell centre). Then level `g`'s
//!   apron (`4 (2^g + 1)` i16), then the mips [`level_mips`]`(g, s, t)`, smallest first.
//!
//! Smooth terrain predicts well, so residuals are small numbers that compress far better than
//! the heights themselves.

use super::{
    Apron, MAX_TEXTURE_SIZE, PartialGrid, Tile, level_mips, level_side, progressive_levels,
};
use crate::db::tiling::{MAX_TILE_SIZE, is_valid_tile_size};
use crate::error::{Error, Result};

/// Bytes of chunk 0 before the corner heights and the texture.
fn head_size(tile_size: usize) -> usize {
    16 + 4 * (tile_size - 1)
}

/// Texels of the mips that progressive level `level` carries.
fn level_texels(level: usize, tile_size: usize, texture_size: usize) -> usize {
    level_mips(level, tile_size, texture_size)
        .map(|m| (texture_size >> m).pow(2))
        .sum()
}

/// Height samples that progressive level `level` adds to the coarser ones.
fn level_samples(level: usize) -> usize {
    if level == 0 {
        4
    } else {
        level_side(level).pow(2) - level_side(level - 1).pow(2)
    }
}

/// The raw (uncompressed) bytes of chunk `level` of a tile of `tile_size` samples and a
/// `texture_size` texture: fixed by the archive header, so a reader knows what to expect.
pub fn level_payload_size(level: usize, tile_size: usize, texture_size: usize) -> usize {
    let head = if level == 0 { head_size(tile_size) } else { 0 };
    head + 2 * level_samples(level)
        + 2 * Apron::level_len(level_side(level))
        + 2 * level_texels(level, tile_size, texture_size)
}

/// Visits the samples of a level's grid (`side` a side, row-major in `grid`) that the coarser
/// levels lack, in the payload's order (row-major), each with its prediction from the coarser
/// level's samples around it: the mean of those left and right of it in the coarser level's
/// rows, of those above and below it in its columns, and of the four diagonal ones elsewhere.
/// Only the coarser level's samples are read, so `visit` may write the sample it is given.
///
/// Row by row rather than position by position through a filter: a tile's arrival refines
/// thousands of samples a frame.
fn new_samples(grid: &mut [u16], side: usize, mut visit: impl FnMut(u16, &mut u16)) {
    debug_assert!(side % 2 == 1 && grid.len() == side * side);
    let mean = |a: u16, b: u16| ((u32::from(a) + u32::from(b)) / 2) as u16;
    for j in 0..side {
        let row = j * side;
        if j % 2 == 0 {
            for i in (1..side).step_by(2) {
                let p = mean(grid[row + i - 1], grid[row + i + 1]);
                visit(p, &mut grid[row + i]);
            }
            continue;
        }
        let (above, below) = (row - side, row + side);
        for i in (0..side).step_by(2) {
            let p = mean(grid[above + i], grid[below + i]);
            visit(p, &mut grid[row + i]);
            if i + 1 < side {
                let corners = [above + i, above + i + 2, below + i, below + i + 2];
                let sum: u32 = corners.iter().map(|&k| u32::from(grid[k])).sum();
                visit((sum / 4) as u16, &mut grid[row + i + 1]);
            }
        }
    }
}

/// Little-endian u16 words of `bytes` (an even number of them).
fn words(bytes: &[u8]) -> impl Iterator<Item = u16> + '_ {
    bytes
        .chunks_exact(2)
        .map(|b| u16::from_le_bytes([b[0], b[1]]))
}

impl Tile {
    /// The raw bytes of progressive chunk `level`, what an archive stores (compressed) for that
    /// level. Panics unless the tile holds `level`.
    pub fn encode_level(&self, level: usize) -> Vec<u8> {
        assert!(
            level < self.levels,
            "tile holds {} levels, not level {level}",
            self.levels
        );
        let (s, t) = (self.tile_size, self.texture_size);
        let mut out = Vec::with_capacity(level_payload_size(level, s, t));
        if level == 0 {
            for v in [self.min.to_le_bytes(), self.max.to_le_bytes()] {
                out.extend_from_slice(&v);
            }
            out.extend_from_slice(&self.base.to_le_bytes());
            out.extend_from_slice(&self.quantum.to_le_bytes());
            for e in &self.level_errors {
                out.extend_from_slice(&e.to_le_bytes());
            }
        }
        let mut push = |w: u16| out.extend_from_slice(&w.to_le_bytes());
        // Level `level`'s grid sample (i, j) is held sample (i * step, j * step).
        let step = 1 << (self.levels - 1 - level);
        let at = |i: usize, j: usize| self.heights[j * step * self.side() + i * step];
        if level == 0 {
            let last = level_side(0) - 1;
            for (i, j) in [(0, 0), (last, 0), (0, last), (last, last)] {
                push(at(i, j));
            }
        } else {
            let side = level_side(level);
            let mut grid: Vec<u16> = (0..side * side).map(|k| at(k % side, k / side)).collect();
            new_samples(&mut grid, side, |p, &mut q| push(q.wrapping_sub(p)));
        }
        for &d in self.apron.level(level) {
            push(d as u16);
        }
        for m in level_mips(level, s, t).rev() {
            self.texture_mips[m - self.first_mip]
                .iter()
                .for_each(|&w| push(w));
        }
        out
    }

    /// Decodes the first `chunks.len()` progressive chunks of a tile of `tile_size` samples and
    /// a `texture_size` texture into the coarser tile they make (equal to the whole tile's
    /// [`Tile::truncated`] to that many levels); `name` labels errors.
    pub fn from_levels(
        chunks: &[&[u8]],
        tile_size: usize,
        texture_size: usize,
        name: &str,
    ) -> Result<Tile> {
        let bad = |p: String| Error::invalid(name, p);
        if !is_valid_tile_size(tile_size) {
            return Err(bad(format!(
                "tile size {tile_size} is not 2^n + 1 up to {MAX_TILE_SIZE}"
            )));
        }
        if !(texture_size.is_power_of_two() && texture_size <= MAX_TEXTURE_SIZE) {
            return Err(bad(format!(
                "texture size {texture_size} is not a power of two up to {MAX_TEXTURE_SIZE}"
            )));
        }
        let all = progressive_levels(tile_size);
        if chunks.is_empty() || chunks.len() > all {
            return Err(bad(format!(
                "{} progressive chunks given, a tile has 1 ..= {all}",
                chunks.len()
            )));
        }
        let mut tile = decode_first(chunks[0], tile_size, texture_size, name)?;
        for chunk in &chunks[1..] {
            tile.refine(chunk, name)?;
        }
        Ok(tile)
    }

    /// Adds the next progressive level from its raw chunk: the result equals decoding one more
    /// chunk with [`Tile::from_levels`]. `name` labels errors; the tile is unchanged on error.
    pub fn refine(&mut self, chunk: &[u8], name: &str) -> Result<()> {
        let level = self.levels;
        if self.is_complete() {
            return Err(Error::invalid(
                name,
                format!("the tile already holds all {level} progressive levels"),
            ));
        }
        let (s, t) = (self.tile_size, self.texture_size);
        let held_mips = level_mips(level - 1, s, t).start;
        if self.heights.len() != self.side().pow(2)
            || self.first_mip != held_mips
            || self.apron.len() != level
        {
            return Err(Error::invalid(
                name,
                format!(
                    "the tile was changed after decoding ({} heights, texture from mip {}, \
                     {} apron levels): refining needs the {} heights, mips from {held_mips} \
                     and apron that its {level} levels decode to",
                    self.heights.len(),
                    self.first_mip,
                    self.apron.len(),
                    self.side().pow(2)
                ),
            ));
        }
        let expected = level_payload_size(level, s, t);
        if chunk.len() != expected {
            return Err(Error::invalid(
                name,
                format!(
                    "progressive level {level} is {} bytes, {expected} expected",
                    chunk.len()
                ),
            ));
        }
        let (old, side) = (self.side(), level_side(level));
        let mut heights = vec![0u16; side * side];
        for j in 0..old {
            for i in 0..old {
                heights[2 * j * side + 2 * i] = self.heights[j * old + i];
            }
        }
        let mut input = words(chunk);
        new_samples(&mut heights, side, |p, q| {
            *q = p.wrapping_add(input.next().expect("length checked"));
        });
        let apron = read_apron(&mut input, side);
        let mut finer: Vec<Vec<u16>> = level_mips(level, s, t)
            .rev()
            .map(|m| input.by_ref().take((t >> m).pow(2)).collect())
            .collect();
        finer.reverse();
        self.first_mip -= finer.len();
        finer.append(&mut self.texture_mips);
        self.texture_mips = finer;
        self.heights = heights;
        self.apron.push(apron);
        self.levels += 1;
        Ok(())
    }
}

/// Decodes chunk 0: the tile's header fields, its corners and its coarsest mips.
fn decode_first(chunk: &[u8], tile_size: usize, texture_size: usize, name: &str) -> Result<Tile> {
    let expected = level_payload_size(0, tile_size, texture_size);
    if chunk.len() != expected {
        return Err(Error::invalid(
            name,
            format!(
                "progressive level 0 is {} bytes, {expected} expected",
                chunk.len()
            ),
        ));
    }
    let f32_at = |k: usize| f32::from_le_bytes(chunk[4 * k..4 * k + 4].try_into().expect("4"));
    let (min, max, quantum) = (f32_at(0), f32_at(1), f32_at(3));
    let base = i32::from_le_bytes(chunk[8..12].try_into().expect("4 bytes"));
    let level_errors: Vec<f32> = (0..tile_size - 1).map(|l| f32_at(4 + l)).collect();
    if ![min, max, quantum]
        .iter()
        .chain(&level_errors)
        .all(|v| v.is_finite())
        || quantum <= 0.0
        || min > max
        || i64::from(base) + i64::from(u16::MAX) > i64::from(i32::MAX)
    {
        return Err(Error::invalid(
            name,
            "tile header holds a non-finite or inconsistent height",
        ));
    }
    let mut input = words(&chunk[head_size(tile_size)..]);
    let heights: Vec<u16> = input.by_ref().take(4).collect();
    let mut apron = Apron::default();
    apron.push(read_apron(&mut input, level_side(0)));
    let mips = level_mips(0, tile_size, texture_size);
    let mut texture_mips: Vec<Vec<u16>> = mips
        .clone()
        .rev()
        .map(|m| input.by_ref().take((texture_size >> m).pow(2)).collect())
        .collect();
    texture_mips.reverse();
    Ok(Tile {
        tile_size,
        levels: 1,
        min,
        max,
        base,
        quantum,
        level_errors,
        heights,
        texture_size,
        first_mip: mips.start,
        texture_mips,
        apron,
    })
}

/// The next level's apron, a grid `side` samples wide, from `input`.
fn read_apron(input: &mut impl Iterator<Item = u16>, side: usize) -> Vec<i16> {
    input
        .take(Apron::level_len(side))
        .map(|w| w as i16)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::db::rgb565::mip_chain_texels;

    /// `new_samples` visits the positions an odd column or row holds, row-major, each
    /// predicted from the coarser samples by the payload format's rule, written position by
    /// position.
    #[test]
    fn new_samples_are_the_odd_positions_with_the_formats_predictions() {
        for side in [3, 5, 9, 17, 65] {
            let mut grid: Vec<u16> = (0..side * side)
                .map(|k| ((k * 40_503) % 65_536) as u16)
                .collect();
            let at = |g: &[u16], i: usize, j: usize| u32::from(g[j * side + i]);
            let mut expected = vec![];
            for j in 0..side {
                for i in 0..side {
                    let p = match (i % 2 == 1, j % 2 == 1) {
                        (false, false) => continue,
                        (true, false) => (at(&grid, i - 1, j) + at(&grid, i + 1, j)) / 2,
                        (false, true) => (at(&grid, i, j - 1) + at(&grid, i, j + 1)) / 2,
                        (true, true) => {
                            (at(&grid, i - 1, j - 1)
                                + at(&grid, i + 1, j - 1)
                                + at(&grid, i - 1, j + 1)
                                + at(&grid, i + 1, j + 1))
                                / 4
                        }
                    };
                    expected.push((j * side + i, p as u16));
                }
            }
            let base = grid.as_ptr() as usize;
            let mut visited = vec![];
            new_samples(&mut grid, side, |p, q| {
                visited.push(((q as *mut u16 as usize - base) / 2, p));
                *q = q.wrapping_mul(3);
            });
            assert_eq!(visited, expected, "side {side}");
        }
    }

    /// A rough tile: heights that wrap residuals both ways, a texture with distinct texels.
    fn tile(s: usize, t: usize) -> Tile {
        let heights: Vec<f32> = (0..s * s)
            .map(|k| ((k * 7919) % 997) as f32 * 0.5 + (k as f32 * 0.37).sin() * 300.0)
            .collect();
        let texture: Vec<[u8; 3]> = (0..t * t)
            .map(|k| [(k * 13) as u8, (k * 29) as u8, (k * 71) as u8])
            .collect();
        Tile::new(&heights, s, 0.0625, &texture, t).unwrap()
    }

    fn chunks(tile: &Tile) -> Vec<Vec<u8>> {
        (0..tile.levels).map(|g| tile.encode_level(g)).collect()
    }

    /// Tile and texture sizes: s = 3 (two levels), t < s - 1, t = s - 1 and t > s - 1.
    const SIZES: [(usize, usize); 6] = [(3, 1), (3, 8), (5, 2), (9, 8), (17, 64), (33, 4)];

    #[test]
    fn every_prefix_decodes_to_exactly_the_truncated_tile() {
        for (s, t) in SIZES {
            let full = tile(s, t);
            let chunks = chunks(&full);
            assert_eq!(chunks.len(), progressive_levels(s));
            for k in 1..=chunks.len() {
                let prefix: Vec<&[u8]> = chunks[..k].iter().map(Vec::as_slice).collect();
                let decoded = Tile::from_levels(&prefix, s, t, "t").unwrap();
                assert_eq!(decoded, full.truncated(k), "s {s}, t {t}, {k} levels");
            }
        }
    }

    #[test]
    fn refine_equals_decoding_one_more_chunk_and_chunks_have_their_sizes() {
        for (s, t) in SIZES {
            let full = tile(s, t);
            let chunks = chunks(&full);
            let mut tile = Tile::from_levels(&[&chunks[0]], s, t, "t").unwrap();
            for (g, chunk) in chunks.iter().enumerate().skip(1) {
                tile.refine(chunk, "t").unwrap();
                assert_eq!(tile, full.truncated(g + 1), "s {s}, t {t}, level {g}");
            }
            let e = tile.refine(&chunks[1], "t").unwrap_err().to_string();
            assert!(e.starts_with("t: ") && e.contains("already holds"), "{e}");
            // Each chunk is its declared size, and together they hold every sample and texel
            // exactly once (the whole-tile size).
            for (g, chunk) in chunks.iter().enumerate() {
                assert_eq!(chunk.len(), level_payload_size(g, s, t));
            }
            let total: usize = chunks.iter().map(Vec::len).sum();
            let apron: usize = (0..progressive_levels(s))
                .map(|g| 2 * Apron::level_len(level_side(g)))
                .sum();
            assert_eq!(
                total,
                16 + 4 * (s - 1) + 2 * s * s + apron + 2 * mip_chain_texels(t)
            );
        }
    }

    #[test]
    fn encoding_a_truncated_tile_gives_the_same_chunks() {
        let full = tile(17, 16);
        let coarse = full.truncated(3);
        for g in 0..3 {
            assert_eq!(coarse.encode_level(g), full.encode_level(g));
        }
    }

    #[test]
    fn residuals_of_a_plane_are_zero() {
        // Heights rising by one quantum per column: every prediction is exact.
        let s = 9;
        let heights: Vec<f32> = (0..s * s).map(|k| (k % s) as f32).collect();
        let tile = Tile::new(&heights, s, 1.0, &[[0, 0, 0]], 1).unwrap();
        for g in 1..tile.levels {
            let chunk = tile.encode_level(g);
            let samples = 2 * level_samples(g);
            assert!(chunk[..samples].iter().all(|&b| b == 0), "level {g}");
        }
    }

    #[test]
    fn wrong_sizes_and_inconsistent_headers_are_named_errors() {
        let (s, t) = (9, 8);
        let chunks = chunks(&tile(s, t));
        let err = |r: Result<Tile>| r.unwrap_err().to_string();
        let e = err(Tile::from_levels(&[], s, t, "f.smdb tile 3"));
        assert!(
            e.starts_with("f.smdb tile 3: ") && e.contains("chunks"),
            "{e}"
        );
        let e = err(Tile::from_levels(&[&chunks[0][1..]], s, t, "f"));
        assert!(e.contains("level 0") && e.contains("expected"), "{e}");
        let e = err(Tile::from_levels(&[&chunks[0], &chunks[2]], s, t, "f"));
        assert!(e.contains("level 1") && e.contains("expected"), "{e}");
        let e = err(Tile::from_levels(&[&chunks[0]], 8, t, "f"));
        assert!(e.contains("tile size 8"), "{e}");
        let e = err(Tile::from_levels(&[&chunks[0]], s, 6, "f"));
        assert!(e.contains("texture size 6"), "{e}");
        let mut bad = chunks[0].clone();
        bad[12..16].copy_from_slice(&(-1.0f32).to_le_bytes());
        let e = err(Tile::from_levels(&[&bad], s, t, "f"));
        assert!(e.contains("inconsistent"), "{e}");
        let mut coarse = Tile::from_levels(&[&chunks[0]], s, t, "f").unwrap();
        let before = coarse.clone();
        assert!(coarse.refine(&chunks[1][..3], "f").is_err());
        assert_eq!(coarse, before, "a failed refine leaves the tile unchanged");
        // A tile whose texture was coarsened after decoding cannot take finer levels.
        coarse.texture_mips.remove(0);
        coarse.first_mip += 1;
        let e = coarse.refine(&chunks[1], "f").unwrap_err().to_string();
        assert!(e.contains("changed after decoding"), "{e}");
    }
}
