//! A tile as the renderer holds it in memory: vertices ready for the rasterizer, the normals they
//! were lit with, and the part of the texture chain its distance needs.
//!
//! Vertices are tile-local integers: `(i, base + q, j)`, grid column, archive-wide height in
//! quanta, grid row. The renderer places a tile with an integer model origin on one shared
//! eye-relative matrix, so the border vertices two tiles share land on the same screen positions
//! (see `stripmask_raster::Transform::with_origin`). Normals are computed once, when the tile is
//! loaded, at the finest level, as the paper does; every mask level reuses them.

use glam::DVec3;
use stripmask_raster::{Texels, Texture, Vertex};

use crate::cracks::{CrackMode, skirts};
use crate::rgb565::mip_count;
use crate::tile::Tile;

/// Light shared by every tile: a direction towards the light and an ambient floor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    /// Direction towards the light, world axes (x east, y up, z south); normalised on use.
    pub direction: DVec3,
    /// Intensity of a surface facing away from the light, 0 ..= 1.
    pub ambient: f64,
}

impl Default for Light {
    /// Late-afternoon sun from the north-west, as cartographers light relief.
    fn default() -> Self {
        Light {
            direction: DVec3::new(-1.0, 1.4, -1.0),
            ambient: 0.35,
        }
    }
}

/// One loaded tile.
#[derive(Clone, Debug)]
pub struct ResidentTile {
    /// `s x s` vertices, row-major from the north-west, then the crack mode's extra vertices
    /// ([`CrackMode::extra_vertices`]).
    pub vertices: Vec<Vertex>,
    /// Unit normals packed as `round(127 n)`, one per grid vertex.
    pub normals: Vec<[i8; 3]>,
    /// The texture from mip `texture_base` of the archive's chain down to 1 x 1.
    pub texture: Texture,
    /// Which mip of the archive's chain this tile's finest texture level is.
    pub texture_base: usize,
    /// Lowest height, metres.
    pub min: f32,
    /// Highest height, metres.
    pub max: f32,
    /// Geometric error of each mask level, metres (from the archive).
    pub level_errors: Vec<f32>,
}

impl ResidentTile {
    /// Builds the resident form of `tile`, keeping texture mips from `texture_base` down (clamped
    /// to the chain), with `spacing` metres between samples, vertex colours lit by `light` and
    /// the extra vertices `cracks` draws.
    pub fn new(
        tile: &Tile,
        texture_base: usize,
        spacing: f64,
        light: &Light,
        cracks: CrackMode,
    ) -> ResidentTile {
        let s = tile.tile_size;
        let normals = normals(tile, spacing);
        let towards = light.direction.normalize_or(DVec3::Y);
        let mut vertices: Vec<Vertex> = (0..s * s)
            .map(|k| {
                let (i, j) = (k % s, k / s);
                let n = normals[k].map(|c| f64::from(c) / 127.0);
                let lit = DVec3::from_array(n).dot(towards).max(0.0);
                let intensity = (light.ambient + (1.0 - light.ambient) * lit).clamp(0.0, 1.0);
                let uv = [i as f32 / (s - 1) as f32, j as f32 / (s - 1) as f32];
                Vertex::new(
                    [i as i32, tile.quanta(i, j), j as i32],
                    uv,
                    [(intensity * 255.0).round() as u8; 3],
                )
            })
            .collect();
        if cracks == CrackMode::Skirts {
            let depth = skirts::depth_quanta(&tile.level_errors, tile.quantum);
            skirts::append_vertices(&mut vertices, s, depth);
        }
        let base = texture_base.min(tile.texture_mips.len() - 1);
        ResidentTile {
            vertices,
            normals,
            texture: chain_from(tile, base),
            texture_base: base,
            min: tile.min,
            max: tile.max,
            level_errors: tile.level_errors.clone(),
        }
    }

    /// Bytes this tile holds: what the memory limit accounts.
    pub fn bytes(&self) -> usize {
        resident_bytes(
            self.vertices.len(),
            self.normals.len(),
            self.level_errors.len(),
            self.texture.byte_size(),
        )
    }

    /// The finest level of [`Self::texture`] worth reading when the tile is drawn at mask level
    /// `mask_level`: texture detail follows the geometric detail the tile's importance bought
    /// (the paper's textures-follow-importance rule). A mask that keeps every `l + 1`-th sample
    /// spans `l + 1` cells per triangle edge, so the archive mip `floor(log2(l + 1))` keeps the
    /// full level's texels per mesh edge; mips the tile no longer holds count as dropped already.
    pub fn finest_texture_level(&self, mask_level: usize) -> u8 {
        let archive_mip = (mask_level + 1).ilog2() as usize;
        let held = self.texture.levels().len() - 1;
        archive_mip.saturating_sub(self.texture_base).min(held) as u8
    }

    /// Adds or removes the skirt vertices so that the tile draws in crack mode `cracks` (heights
    /// in archive quanta of `quantum` metres), exactly as if it had been loaded in that mode:
    /// switching modes needs no fetch. Returns the bytes the tile holds now.
    pub fn set_cracks(&mut self, cracks: CrackMode, quantum: f32) -> usize {
        let grid = self.normals.len();
        let s = grid.isqrt();
        if self.vertices.len() != grid + cracks.extra_vertices(s) {
            self.vertices.truncate(grid);
            if cracks == CrackMode::Skirts {
                let depth = skirts::depth_quanta(&self.level_errors, quantum);
                skirts::append_vertices(&mut self.vertices, s, depth);
            }
            self.vertices.shrink_to_fit();
        }
        self.bytes()
    }

    /// Drops texture mips finer than `base` (no-op when already coarser); returns the new bytes.
    pub fn coarsen_texture(&mut self, base: usize) -> usize {
        let drop = base.saturating_sub(self.texture_base);
        let levels = self.texture.levels();
        if drop > 0 && drop < levels.len() {
            let kept = levels[drop..]
                .iter()
                .map(|l| (l.width(), l.height(), l.texels().clone()))
                .collect();
            self.texture = Texture::from_levels(kept).expect("a tail of a mip chain is a chain");
            self.texture_base += drop;
        }
        self.bytes()
    }
}

/// The bytes a resident tile of `tile_size` samples holds with its texture from mip `base` of a
/// `texture_size` RGB565 chain, drawn in crack mode `cracks`, known before the tile is fetched.
pub fn predicted_bytes(
    tile_size: usize,
    texture_size: usize,
    base: usize,
    cracks: CrackMode,
) -> usize {
    let base = base.min(mip_count(texture_size) - 1);
    let texels: usize = (base..mip_count(texture_size))
        .map(|l| (texture_size >> l).pow(2))
        .sum();
    let grid = tile_size * tile_size;
    resident_bytes(
        grid + cracks.extra_vertices(tile_size),
        grid,
        tile_size - 1,
        2 * texels,
    )
}

fn resident_bytes(vertices: usize, normals: usize, levels: usize, texture_bytes: usize) -> usize {
    std::mem::size_of::<ResidentTile>()
        + vertices * std::mem::size_of::<Vertex>()
        + normals * std::mem::size_of::<[i8; 3]>()
        + levels * std::mem::size_of::<f32>()
        + texture_bytes
}

/// Unit normals at the finest level from central differences (one-sided at the tile border,
/// where the neighbour's samples are not at hand).
fn normals(tile: &Tile, spacing: f64) -> Vec<[i8; 3]> {
    let s = tile.tile_size;
    let h = |i: usize, j: usize| f64::from(tile.height(i, j));
    (0..s * s)
        .map(|k| {
            let (i, j) = (k % s, k / s);
            let (i0, i1) = (i.saturating_sub(1), (i + 1).min(s - 1));
            let (j0, j1) = (j.saturating_sub(1), (j + 1).min(s - 1));
            let dhdx = (h(i1, j) - h(i0, j)) / ((i1 - i0) as f64 * spacing);
            let dhdz = (h(i, j1) - h(i, j0)) / ((j1 - j0) as f64 * spacing);
            let n = DVec3::new(-dhdx, 1.0, -dhdz).normalize();
            n.to_array().map(|c| (c * 127.0).round() as i8)
        })
        .collect()
}

fn chain_from(tile: &Tile, base: usize) -> Texture {
    let t = tile.texture_size;
    let levels = tile.texture_mips[base..]
        .iter()
        .enumerate()
        .map(|(k, texels)| {
            let side = (t >> (base + k)).max(1) as u32;
            (side, side, Texels::Rgb565(texels.clone()))
        })
        .collect();
    Texture::from_levels(levels).expect("a decoded tile holds a complete RGB565 mip chain")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sloped_tile() -> Tile {
        let s = 9;
        // Rises 1 m per metre eastwards with a 2 m spacing: dh/dx = 1.
        let heights: Vec<f32> = (0..s * s).map(|k| 2.0 * (k % s) as f32).collect();
        Tile::new(&heights, s, 0.0625, &[[90, 120, 60]; 64], 8).unwrap()
    }

    #[test]
    fn vertices_carry_grid_indices_and_archive_quanta() {
        let tile = sloped_tile();
        let r = ResidentTile::new(&tile, 0, 2.0, &Light::default(), CrackMode::None);
        assert_eq!(r.vertices.len(), 81);
        let v = r.vertices[2 * 9 + 3];
        assert_eq!(v.position, [3, tile.quanta(3, 2), 2]);
        assert_eq!(tile.quanta(3, 2), 96);
        assert_eq!(v.uv.map(|c| c.to_num::<f32>()), [3.0 / 8.0, 2.0 / 8.0]);
    }

    #[test]
    fn normals_follow_the_slope_and_light_follows_the_normals() {
        let tile = sloped_tile();
        // A 45° slope facing west: the normal is (-1, 1, 0) / sqrt 2.
        let r = ResidentTile::new(&tile, 0, 2.0, &Light::default(), CrackMode::None);
        for n in &r.normals {
            assert_eq!(*n, [-90, 90, 0]);
        }
        let west = Light {
            direction: DVec3::new(-1.0, 1.0, 0.0),
            ambient: 0.2,
        };
        let east = Light {
            direction: DVec3::new(1.0, 1.0, 0.0),
            ambient: 0.2,
        };
        let lit = ResidentTile::new(&tile, 0, 2.0, &west, CrackMode::None).vertices[40].color[0];
        let dark = ResidentTile::new(&tile, 0, 2.0, &east, CrackMode::None).vertices[40].color[0];
        assert_eq!(lit, 255);
        assert_eq!(dark, (0.2f64 * 255.0).round() as u8);
    }

    #[test]
    fn accounted_bytes_are_known_before_loading_and_shrink_with_the_texture() {
        let tile = sloped_tile();
        for base in 0..5 {
            for cracks in CrackMode::ALL {
                let r = ResidentTile::new(&tile, base, 2.0, &Light::default(), cracks);
                assert_eq!(r.bytes(), predicted_bytes(9, 8, base, cracks), "{cracks:?}");
            }
        }
        let skirted = ResidentTile::new(&tile, 0, 2.0, &Light::default(), CrackMode::Skirts);
        for from in CrackMode::ALL {
            for to in CrackMode::ALL {
                let mut r = ResidentTile::new(&tile, 1, 2.0, &Light::default(), from);
                let fresh = ResidentTile::new(&tile, 1, 2.0, &Light::default(), to);
                assert_eq!(
                    r.set_cracks(to, tile.quantum),
                    fresh.bytes(),
                    "{from:?} -> {to:?}"
                );
                assert_eq!(r.vertices, fresh.vertices, "{from:?} -> {to:?}");
            }
        }
        assert_eq!(skirted.vertices.len(), 81 + 36);
        let mut r = ResidentTile::new(&tile, 0, 2.0, &Light::default(), CrackMode::None);
        let full = r.bytes();
        assert_eq!(r.texture.levels().len(), 4);
        let smaller = r.coarsen_texture(2);
        assert_eq!(r.texture_base, 2);
        assert_eq!(r.texture.levels()[0].width(), 2);
        assert_eq!(smaller, predicted_bytes(9, 8, 2, CrackMode::None));
        assert_eq!(full - smaller, 2 * (64 + 16));
        assert_eq!(r.coarsen_texture(1), smaller, "never refines");
    }

    #[test]
    fn texture_detail_follows_the_mask_level_and_what_the_tile_holds() {
        let tile = sloped_tile();
        let full = ResidentTile::new(&tile, 0, 2.0, &Light::default(), CrackMode::None);
        // Mask levels 0..7 keep every 1st..8th sample: archive mips 0, 1, 1, 2, 2, 2, 2, 3.
        let levels: Vec<u8> = (0..8).map(|l| full.finest_texture_level(l)).collect();
        assert_eq!(levels, [0, 1, 1, 2, 2, 2, 2, 3]);
        let coarse = ResidentTile::new(&tile, 2, 2.0, &Light::default(), CrackMode::None);
        let levels: Vec<u8> = (0..8).map(|l| coarse.finest_texture_level(l)).collect();
        assert_eq!(levels, [0, 0, 0, 0, 0, 0, 0, 1], "mips from 2 on are held");
        assert_eq!(
            full.finest_texture_level(1000),
            3,
            "never past the last level"
        );
    }
}
