//! The tile payload: what the runtime needs for one tile and nothing more.
//!
//! Layout before compression (all little-endian), for a tile of `s` samples per side, `L = s - 1`
//! mask levels and a texture of side `t` with `M = log2(t) + 1` mip levels:
//!
//! | bytes | field |
//! | --- | --- |
//! | 4 | `min` f32, lowest height (metres) |
//! | 4 | `max` f32, highest height (metres) |
//! | 4 | `offset` f32 (metres) |
//! | 4 | `scale` f32 (metres per quantum); height = offset + q * scale |
//! | 4 L | `level_errors` f32, level 0 first (see [`crate::level_error`]) |
//! | 2 s² | heights `q` u16, row-major, each row delta-coded: `q[0]`, then `q[i] - q[i-1]` wrapping |
//! | 2 (t² + (t/2)² + … + 1) | texture RGB565 u16, finest mip first, each row-major |
//!
//! Quantisation: `scale = (max - min) / 65535` and `offset = min`, so a decoded height is within
//! `scale / 2` (plus f32 rounding) of the true one. The payload size is fixed by `s` and `t`,
//! which the archive header carries.

use crate::error::{Error, Result};
use crate::level_error::level_errors;
use crate::mask_level::level_count;
use crate::rgb565::{mip_chain, mip_chain_texels, mip_count};

/// One decoded tile.
#[derive(Clone, Debug, PartialEq)]
pub struct Tile {
    /// Samples per side.
    pub tile_size: usize,
    /// Lowest height in metres.
    pub min: f32,
    /// Highest height in metres.
    pub max: f32,
    /// Metres of quantum 0.
    pub offset: f32,
    /// Metres per quantum.
    pub scale: f32,
    /// Maximum geometric error of each mask level against the full tile, metres, level 0 first.
    pub level_errors: Vec<f32>,
    /// Quantised heights, `tile_size^2`, row-major from the north-west.
    pub heights: Vec<u16>,
    /// Texture side in texels (finest mip).
    pub texture_size: usize,
    /// RGB565 mip chain, finest first, down to 1 x 1.
    pub texture_mips: Vec<Vec<u16>>,
}

/// The uncompressed payload size of a tile with `tile_size` samples and a `texture_size` texture.
pub fn payload_size(tile_size: usize, texture_size: usize) -> usize {
    16 + 4 * level_count(tile_size) + 2 * tile_size * tile_size + 2 * mip_chain_texels(texture_size)
}

impl Tile {
    /// Builds a tile from `s x s` heights in metres and its finest texture (RGB, side `t`).
    pub fn new(
        heights: &[f32],
        tile_size: usize,
        texture: &[[u8; 3]],
        texture_size: usize,
    ) -> Tile {
        let (min, max) = heights
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &h| {
                (lo.min(h), hi.max(h))
            });
        let scale = (max - min) / f32::from(u16::MAX);
        let quantised = heights
            .iter()
            .map(|&h| {
                if scale > 0.0 {
                    ((h - min) / scale).round().clamp(0.0, 65535.0) as u16
                } else {
                    0
                }
            })
            .collect();
        Tile {
            tile_size,
            min,
            max,
            offset: min,
            scale,
            level_errors: level_errors(heights, tile_size),
            heights: quantised,
            texture_size,
            texture_mips: mip_chain(texture, texture_size),
        }
    }

    /// The height in metres of sample `(i, j)`.
    pub fn height(&self, i: usize, j: usize) -> f32 {
        self.offset + f32::from(self.heights[j * self.tile_size + i]) * self.scale
    }

    /// The uncompressed payload bytes.
    pub fn encode(&self) -> Vec<u8> {
        let s = self.tile_size;
        let mut out = Vec::with_capacity(payload_size(s, self.texture_size));
        for v in [self.min, self.max, self.offset, self.scale] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        for e in &self.level_errors {
            out.extend_from_slice(&e.to_le_bytes());
        }
        for row in self.heights.chunks_exact(s) {
            let mut prev = 0u16;
            for &q in row {
                out.extend_from_slice(&q.wrapping_sub(prev).to_le_bytes());
                prev = q;
            }
        }
        for mip in &self.texture_mips {
            for t in mip {
                out.extend_from_slice(&t.to_le_bytes());
            }
        }
        out
    }

    /// Decodes an uncompressed payload; `name` labels errors.
    pub fn decode(bytes: &[u8], tile_size: usize, texture_size: usize, name: &str) -> Result<Tile> {
        let expected = payload_size(tile_size, texture_size);
        if bytes.len() != expected {
            return Err(Error::invalid(
                name,
                format!("tile payload is {} bytes, {expected} expected", bytes.len()),
            ));
        }
        let f32_at =
            |k: usize| f32::from_le_bytes(bytes[4 * k..4 * k + 4].try_into().expect("4 bytes"));
        let (min, max, offset, scale) = (f32_at(0), f32_at(1), f32_at(2), f32_at(3));
        let levels = level_count(tile_size);
        let level_errors: Vec<f32> = (0..levels).map(|l| f32_at(4 + l)).collect();
        if ![min, max, offset, scale]
            .iter()
            .chain(&level_errors)
            .all(|v| v.is_finite())
            || scale < 0.0
            || min > max
        {
            return Err(Error::invalid(
                name,
                "tile header holds a non-finite or inconsistent height",
            ));
        }
        let mut words = bytes[16 + 4 * levels..]
            .chunks_exact(2)
            .map(|b| u16::from_le_bytes([b[0], b[1]]));
        let mut heights = Vec::with_capacity(tile_size * tile_size);
        for _ in 0..tile_size {
            let mut prev = 0u16;
            for _ in 0..tile_size {
                prev = prev.wrapping_add(words.next().expect("length checked"));
                heights.push(prev);
            }
        }
        let texture_mips = (0..mip_count(texture_size))
            .map(|l| words.by_ref().take((texture_size >> l).pow(2)).collect())
            .collect();
        Ok(Tile {
            tile_size,
            min,
            max,
            offset,
            scale,
            level_errors,
            heights,
            texture_size,
            texture_mips,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn encode_decode_round_trip_within_half_a_quantum() {
        let s = 9;
        let heights: Vec<f32> = (0..s * s)
            .map(|k| (k as f32 * 0.37).sin() * 500.0)
            .collect();
        let texture = vec![[10, 200, 30]; 64];
        let tile = Tile::new(&heights, s, &texture, 8);
        let bytes = tile.encode();
        assert_eq!(bytes.len(), payload_size(s, 8));
        let back = Tile::decode(&bytes, s, 8, "t").unwrap();
        assert_eq!(back, tile);
        for j in 0..s {
            for i in 0..s {
                assert!((back.height(i, j) - heights[j * s + i]).abs() <= tile.scale * 0.5 + 1e-3);
            }
        }
        assert!(Tile::decode(&bytes[1..], s, 8, "t").is_err());
    }
}
