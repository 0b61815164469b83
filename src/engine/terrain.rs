//! Where an archive's tiles sit in the world: the grid geometry the pager and the renderer share.

use glam::DVec3;

use crate::db::archive::Header;
use crate::db::grid::{Pyramid, TileId};
use crate::db::tile::PartialGrid;
use crate::engine::resident::ResidentTile;

/// The terrain's placement and grid, from an archive header.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TerrainFrame {
    /// Tiles across (east).
    pub tiles_x: u32,
    /// Tiles down (south).
    pub tiles_y: u32,
    /// Samples per tile side.
    pub tile_size: usize,
    /// Metres between samples.
    pub spacing: f64,
    /// Metres per height quantum.
    pub quantum: f64,
    /// Lowest and highest height of the archive, metres.
    pub heights: (f64, f64),
    /// World position of the north-west sample at height 0. Zero by default; a large value
    /// places the terrain far from the origin (the renderer is eye-relative, so it draws the same).
    pub origin: DVec3,
    /// Samples per row and rows of the model itself: the grid of whole tiles is padded east and
    /// south beyond them, and the padding is never drawn or flown over.
    pub source_samples: (u32, u32),
    /// The archive's own coordinates (east, north) of the north-west sample, as `build` stored
    /// them (projected metres, say): where a position given in those coordinates lands.
    pub archive_origin: (f64, f64),
}

impl TerrainFrame {
    /// The frame of an archive, placed at the world origin.
    pub fn new(header: &Header) -> TerrainFrame {
        TerrainFrame {
            tiles_x: header.tiles_x,
            tiles_y: header.tiles_y,
            tile_size: header.tile_size as usize,
            spacing: header.spacing,
            quantum: f64::from(header.height_quantum),
            heights: (f64::from(header.min_height), f64::from(header.max_height)),
            origin: DVec3::ZERO,
            source_samples: (header.source_width, header.source_height),
            archive_origin: (header.origin_x, header.origin_y),
        }
    }

    /// The world point at `east` and `north` in the archive's own coordinates
    /// ([`Self::archive_origin`]'s) and `altitude` metres up.
    pub fn from_archive(&self, east: f64, north: f64, altitude: f64) -> DVec3 {
        let (e0, n0) = self.archive_origin;
        self.origin + DVec3::new(east - e0, altitude, n0 - north)
    }

    /// East-west and north-south extent of the model's own samples, metres: the grid's
    /// [`Self::extent`] without the padding that makes its tiles whole.
    pub fn source_extent(&self) -> (f64, f64) {
        let (w, h) = self.source_samples;
        (
            f64::from(w.saturating_sub(1)) * self.spacing,
            f64::from(h.saturating_sub(1)) * self.spacing,
        )
    }

    /// The last position east and south of tile `id`, in level-0 samples from its north-west
    /// sample, that belongs to the model (`(tile_size - 1) 2^level` for a tile without
    /// padding): what [`ResidentTile::clipped`] cuts at.
    pub fn tile_extent(&self, id: TileId) -> [i32; 2] {
        let span = i64::from(id.span());
        let cells = (self.tile_size as i64 - 1) * span;
        let last = |t: u32, samples: u32| {
            (i64::from(samples) - 1 - i64::from(t) * cells).clamp(0, cells) as i32
        };
        [
            last(id.x, self.source_samples.0),
            last(id.y, self.source_samples.1),
        ]
    }

    /// The pyramid over the grid of level-0 tiles.
    pub fn pyramid(&self) -> Pyramid {
        Pyramid::new(self.tiles_x, self.tiles_y).expect("an archive's grid has tiles")
    }

    /// Metres along one tile side.
    pub fn tile_metres(&self) -> f64 {
        (self.tile_size - 1) as f64 * self.spacing
    }

    /// East-west and north-south extent of the whole grid, metres.
    pub fn extent(&self) -> (f64, f64) {
        (
            f64::from(self.tiles_x) * self.tile_metres(),
            f64::from(self.tiles_y) * self.tile_metres(),
        )
    }

    /// The viewer's position in tile units (x east, y south): tile `(tx, ty)` covers
    /// `tx ..= tx + 1` and `ty ..= ty + 1`. Off the terrain the values fall outside the grid.
    pub fn tile_position(&self, world: DVec3) -> (f64, f64) {
        let rel = world - self.origin;
        (rel.x / self.tile_metres(), rel.z / self.tile_metres())
    }

    /// Metres along one side of a tile of pyramid level `level`.
    pub fn level_metres(&self, level: u8) -> f64 {
        self.tile_metres() * f64::from(1u32 << level)
    }

    /// World position of tile `id`'s north-west sample at height 0.
    pub fn tile_origin(&self, id: TileId) -> DVec3 {
        let side = self.level_metres(id.level);
        self.origin + DVec3::new(f64::from(id.x) * side, 0.0, f64::from(id.y) * side)
    }

    /// The world bounding box of tile `id` with heights `min ..= max` metres.
    pub fn tile_box(&self, id: TileId, min: f64, max: f64) -> (DVec3, DVec3) {
        let o = self.tile_origin(id);
        let side = self.level_metres(id.level);
        (
            o + DVec3::new(0.0, min, 0.0),
            o + DVec3::new(side, max, side),
        )
    }

    /// The terrain height under world position `(x, z)` in the samples of tile `id`, bilinear
    /// over the grid it holds (a partial tile's coarser grid), or `None` when the point is not
    /// over that tile or the tile is absent.
    pub fn ground_in(&self, tile: &ResidentTile, id: TileId, world: DVec3) -> Option<f64> {
        if tile.absent {
            return None;
        }
        let o = self.tile_origin(id);
        let spacing = self.spacing * f64::from(id.span());
        let (u, v) = ((world.x - o.x) / spacing, (world.z - o.z) / spacing);
        let last = (self.tile_size - 1) as f64;
        if !(0.0..=last).contains(&u) || !(0.0..=last).contains(&v) {
            return None;
        }
        let (s, stride) = (tile.side(), tile.stride() as f64);
        let (u, v) = (u / stride, v / stride);
        let (i, j) = ((u as usize).min(s - 2), (v as usize).min(s - 2));
        let (fu, fv) = (u - i as f64, v - j as f64);
        let h = |a: usize, b: usize| f64::from(tile.vertices[b * s + a].position[1]) * self.quantum;
        let top = h(i, j) * (1.0 - fu) + h(i + 1, j) * fu;
        let bottom = h(i, j + 1) * (1.0 - fu) + h(i + 1, j + 1) * fu;
        Some(o.y + top * (1.0 - fv) + bottom * fv)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::db::tile::Tile;
    use crate::engine::cracks::CrackMode;
    use crate::engine::shading::Light;

    #[test]
    fn ground_under_a_partial_tile_is_the_bilinear_height_of_its_held_grid() {
        let s = 9;
        let heights: Vec<f32> = (0..s * s)
            .map(|k| 40.0 * ((k % s) as f32 * 1.7).sin() + 9.0 * (k / s) as f32)
            .collect();
        let whole = Tile::new(&heights, s, 0.25, &[[9, 9, 9]; 16], 4).unwrap();
        let frame = TerrainFrame {
            tiles_x: 3,
            tiles_y: 2,
            tile_size: s,
            spacing: 5.0,
            quantum: 0.25,
            heights: (-40.0, 120.0),
            origin: DVec3::new(1000.0, 7.0, -500.0),
            source_samples: (3 * (s as u32 - 1) + 1, 2 * (s as u32 - 1) + 1),
            archive_origin: (0.0, 0.0),
        };
        for levels in 1..=whole.levels {
            let tile = whole.truncated(levels);
            let r = ResidentTile::new(&tile, 0, 5.0, Some(&Light::default()), CrackMode::Skirts);
            let step = 5.0 * tile.stride() as f64;
            let o = frame.tile_origin(TileId::new(2, 1));
            for (x, z) in [
                (0.0, 0.0),
                (13.0, 27.5),
                (39.9, 1.0),
                (40.0, 40.0),
                (21.0, 40.0),
            ] {
                let (u, v) = (x / step, z / step);
                let last = tile.side() - 2;
                let (i, j) = ((u as usize).min(last), (v as usize).min(last));
                let (fu, fv) = (u - i as f64, v - j as f64);
                let h = |a: usize, b: usize| f64::from(tile.quanta(a, b)) * 0.25;
                let expected = o.y
                    + (h(i, j) * (1.0 - fu) + h(i + 1, j) * fu) * (1.0 - fv)
                    + (h(i, j + 1) * (1.0 - fu) + h(i + 1, j + 1) * fu) * fv;
                let got = frame
                    .ground_in(&r, TileId::new(2, 1), o + DVec3::new(x, 0.0, z))
                    .unwrap();
                assert!(
                    (got - expected).abs() < 1e-9,
                    "{levels} levels at ({x}, {z})"
                );
            }
            assert!(
                frame
                    .ground_in(&r, TileId::new(2, 1), o + DVec3::new(40.5, 0.0, 3.0))
                    .is_none()
            );
        }
    }
}
