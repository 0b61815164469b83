//! A tile as the renderer holds it in memory: vertices ready for the rasterizer, the normals they
//! were lit with, and the part of the texture chain its distance needs.
//!
//! Vertices are tile-local integers: `(x, base + q, z)`, east and south from the tile's
//! north-west sample in level-0 samples (a tile of pyramid level `k` spans `2^k` times as
//! many), archive-wide height in quanta. The renderer places a tile with an integer model
//! origin on one shared eye-relative matrix, so the border vertices two tiles share — of the
//! same level or of two — land on the same screen positions
//! (see `stripmask_raster::Transform::with_origin`). Lighting is computed once, when the tile is
//! loaded, for every progressive level it holds: each level's normals are central differences
//! over that level's grid, the border included (the level's apron, the samples just outside
//! the tile's borders stored by the builder, gives the other side). A tile drawn at a mask
//! level is lit from the grid that mask needs ([`levels_for_mask`]), whole or partial: the
//! prefiltered normals of the geometry drawn, so two tiles drawing the same level light the
//! vertices they share alike (no line along their border), and a partial tile draws exactly
//! the whole tile's pixels at the same level. A tile loaded while the frame is unlit (textured
//! without vertex lighting, the default) holds no normals or shades and white vertices: on a
//! core without an FPU the normals are a twentieth of the frame.

use stripmask_raster::fixed_point::TexCoord;
use stripmask_raster::{Texels, Texture, Vertex};

use crate::db::rgb565::mip_count;
use crate::db::tile::{
    Apron, PartialGrid, Tile, level_mips, level_side, levels_for_mask, progressive_levels,
    texture_coordinate, texture_coordinate_at,
};
use crate::engine::cracks::{CrackMode, skirts};
use crate::engine::normals::SlopeNormals;
use crate::engine::shading::{Light, Shading};

/// One loaded tile, whole or holding only its first progressive levels ([`Tile::levels`]).
///
/// A partial tile holds a compact grid of [`ResidentTile::side`] vertices per side, every
/// [`ResidentTile::stride`]-th sample of the whole tile, so its memory shrinks with the levels
/// it lacks. Vertex positions stay in whole-tile grid units (`(ci * stride, base + q, cj *
/// stride)`): the shared frame transform and integer tile origin place it, and the border
/// vertices it shares with a neighbour are bit-identical to the neighbour's.
#[derive(Clone, Debug)]
pub struct ResidentTile {
    /// `side x side` vertices, row-major from the north-west, then the crack mode's extra
    /// vertices ([`CrackMode::extra_vertices`] of the side).
    pub vertices: Vec<Vertex>,
    /// Unit normals packed as `round(127 n)`, one per grid vertex; none when unlit.
    pub normals: Vec<[i8; 3]>,
    /// Per coarser held level `g < levels - 1`, the light intensity of each of its
    /// `(2^g + 1)^2` samples lit from that level's own grid: what a draw at a mask that needs
    /// only level `g` colours its vertices with ([`ResidentTile::lit_vertices`]); none when
    /// unlit.
    pub coarse_shades: Vec<Vec<u8>>,
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
    /// Samples per side of the whole tile.
    pub tile_size: usize,
    /// Progressive levels held (see [`crate::db::tile::progressive_levels`]).
    pub levels: usize,
    /// The tile's quantum 0 in archive quanta: a vertex height is `base + q`.
    pub base: i32,
    /// Metres per height quantum.
    pub quantum: f32,
    /// Metres between level-0 samples (the normals were computed with `scale` times that).
    pub spacing: f64,
    /// Level-0 samples between two whole-tile samples of this tile: `2^level` for a tile of
    /// pyramid level `level`.
    pub scale: u32,
    /// Every sample of the tile was nodata: nothing is stored and nothing is drawn (no vertex,
    /// no texel).
    pub absent: bool,
    /// The light the vertex colours were lit with; `None`: unlit, the vertices white.
    pub light: Option<Light>,
    /// The samples just outside the borders of each held level: kept so that the tile can be
    /// given back ([`ResidentTile::to_tile`]) and refined or truncated.
    pub apron: Apron,
    /// The last position east and south, in level-0 samples from the tile's north-west
    /// sample, that belongs to the model
    /// ([`TerrainFrame::tile_extent`](crate::engine::terrain::TerrainFrame::tile_extent)):
    /// vertices beyond it, on the padding that makes the tile whole, lie on it instead.
    pub extent: [i32; 2],
}

impl PartialGrid for ResidentTile {
    fn whole_size(&self) -> usize {
        self.tile_size
    }

    fn held_levels(&self) -> usize {
        self.levels
    }
}

impl ResidentTile {
    /// Builds the resident form of `tile` (whole or partial), keeping texture mips from
    /// `texture_base` down (never finer than the tile holds, clamped to the chain), with
    /// `spacing` metres between samples, vertex colours lit by `light` (white and no normals
    /// held when `None`) and the extra vertices `cracks` draws.
    pub fn new(
        tile: &Tile,
        texture_base: usize,
        spacing: f64,
        light: Option<&Light>,
        cracks: CrackMode,
    ) -> ResidentTile {
        ResidentTile::of_level(tile, 0, texture_base, spacing, light, cracks)
    }

    /// [`ResidentTile::new`] for a tile of pyramid level `level`, whose samples are `2^level`
    /// level-0 samples of `spacing` metres apart.
    pub fn of_level(
        tile: &Tile,
        level: u8,
        texture_base: usize,
        spacing: f64,
        light: Option<&Light>,
        cracks: CrackMode,
    ) -> ResidentTile {
        ResidentTile::lit_over(None, tile, level, texture_base, spacing, light, cracks)
    }

    /// [`ResidentTile::of_level`] of `tile` refined from `held`, the resident form of its first
    /// levels: the levels `held` lit under the same light keep their shades. A tile's levels
    /// arrive one after another, and each arrival would light them all again.
    pub fn refined(
        held: &ResidentTile,
        tile: &Tile,
        level: u8,
        texture_base: usize,
        spacing: f64,
        light: Option<&Light>,
        cracks: CrackMode,
    ) -> ResidentTile {
        let same_grid = !held.absent
            && held.light.as_ref() == light
            && held.spacing == spacing
            && held.scale == 1 << level
            && held.levels <= tile.levels;
        let held = same_grid.then_some(held);
        ResidentTile::lit_over(held, tile, level, texture_base, spacing, light, cracks)
    }

    /// [`ResidentTile::of_level`], the shades of the levels `held` lit taken from it.
    fn lit_over(
        held: Option<&ResidentTile>,
        tile: &Tile,
        level: u8,
        texture_base: usize,
        spacing: f64,
        light: Option<&Light>,
        cracks: CrackMode,
    ) -> ResidentTile {
        let scale = 1u32 << level;
        let (side, stride) = (tile.side(), tile.stride());
        let step = stride * scale as usize;
        let level_spacing =
            |g: usize| spacing * f64::from(scale) * ((tile.tile_size - 1) >> g) as f64;
        let (normals, coarse_shades, shades) = match light {
            Some(light) => {
                let shading = Shading::new(light);
                let normals = normals(tile, tile.levels - 1, level_spacing(tile.levels - 1));
                let coarse_shades = (0..tile.levels - 1)
                    .map(|g| match held {
                        Some(held) if g + 1 < held.levels => held.coarse_shades[g].clone(),
                        Some(held) if g + 1 == held.levels => {
                            held.normals.iter().map(|&n| shading.of(n)).collect()
                        }
                        _ => {
                            let normals = self::normals(tile, g, level_spacing(g));
                            normals.iter().map(|&n| shading.of(n)).collect()
                        }
                    })
                    .collect();
                let shades: Vec<u8> = normals.iter().map(|&n| shading.of(n)).collect();
                (normals, coarse_shades, Some(shades))
            }
            None => (Vec::new(), Vec::new(), None),
        };
        // One texture coordinate per column (and row), converted once: on a core without an
        // FPU each is a few library calls.
        let coords: Vec<TexCoord> = (0..side)
            .map(|i| {
                let c = texture_coordinate(i * stride, tile.tile_size, tile.texture_size);
                TexCoord::saturating_from_num(c)
            })
            .collect();
        // Row by row, not `k / side` per vertex: a library call on a core without a divider.
        // Unlit, every vertex is white.
        debug_assert!(shades.as_ref().is_none_or(|s| s.len() == side * side));
        let mut vertices: Vec<Vertex> = Vec::with_capacity(side * side);
        for j in 0..side {
            let row_shades = shades.as_ref().map(|s| &s[j * side..(j + 1) * side]);
            for (i, quanta) in tile.quanta_row(j).enumerate() {
                let shade = row_shades.map_or(u8::MAX, |s| s[i]);
                vertices.push(Vertex {
                    position: [(i * step) as i32, quanta, (j * step) as i32],
                    uv: [coords[i], coords[j]],
                    color: [shade; 3],
                });
            }
        }
        if cracks == CrackMode::Skirts {
            let depth = skirts::depth_quanta(&tile.level_errors, tile.quantum);
            skirts::append_vertices(&mut vertices, side, depth);
        }
        let held = tile.first_mip..tile.first_mip + tile.texture_mips.len();
        let base = texture_base.clamp(held.start, held.end - 1);
        ResidentTile {
            vertices,
            normals,
            coarse_shades,
            texture: chain_from(tile, base),
            texture_base: base,
            min: tile.min,
            max: tile.max,
            level_errors: tile.level_errors.clone(),
            tile_size: tile.tile_size,
            levels: tile.levels,
            base: tile.base,
            quantum: tile.quantum,
            spacing,
            scale,
            absent: false,
            light: light.copied(),
            apron: tile.apron.clone(),
            extent: [(tile.tile_size as i32 - 1) * scale as i32; 2],
        }
    }

    /// The resident form of an absent tile of `tile_size` samples of pyramid level `level`:
    /// nothing to draw, a few bytes to account.
    pub fn absent(
        tile_size: usize,
        level: u8,
        spacing: f64,
        light: Option<&Light>,
    ) -> ResidentTile {
        let scale = 1u32 << level;
        ResidentTile {
            vertices: Vec::new(),
            normals: Vec::new(),
            coarse_shades: Vec::new(),
            texture: Texture::from_levels(vec![(1, 1, Texels::Rgb565(vec![0]))])
                .expect("a 1 x 1 texture is a chain"),
            texture_base: mip_count(tile_size.max(2) - 1) - 1,
            min: 0.0,
            max: 0.0,
            level_errors: Vec::new(),
            tile_size,
            levels: progressive_levels(tile_size),
            base: 0,
            quantum: 1.0,
            spacing,
            scale,
            absent: true,
            light: light.copied(),
            apron: Apron::default(),
            extent: [(tile_size as i32 - 1) * scale as i32; 2],
        }
    }

    /// The tile cut at `extent`, the last sample index east and south that belongs to the
    /// model: every vertex beyond it (on the padding, whose samples repeat the model's last
    /// column and row) moves onto it, texture coordinates with it. Triangles wholly on the
    /// padding collapse to nothing, and those that straddle the edge end exactly at the
    /// model's last samples, so the terrain stops at the model's extent without a crack: the
    /// same rule moves the vertices two tiles share to the same place.
    pub fn clipped(mut self, extent: [i32; 2]) -> ResidentTile {
        self.extent = extent;
        let (s, t) = (self.tile_size, self.texture_size());
        let scale = f64::from(self.scale);
        let at = |x: i32| texture_coordinate_at(f64::from(x) / scale, s, t);
        for v in &mut self.vertices {
            let [x, y, z] = v.position;
            let (cx, cz) = (x.min(extent[0]), z.min(extent[1]));
            if (cx, cz) != (x, z) {
                *v = Vertex::new([cx, y, cz], [at(cx), at(cz)], v.color);
            }
        }
        self
    }

    /// The tile this resident form was built from, as far as it holds it: the held heights
    /// (from the vertices) and the held texture mips. What the pager needs to rebuild a tile in
    /// another form without fetching it again.
    pub fn to_tile(&self) -> Tile {
        let grid = self.side() * self.side();
        let texture_mips = self
            .texture
            .levels()
            .iter()
            .map(|l| match l.texels() {
                Texels::Rgb565(t) => t.clone(),
                other => unreachable!("resident textures are RGB565, not {other:?}"),
            })
            .collect();
        Tile {
            tile_size: self.tile_size,
            levels: self.levels,
            min: self.min,
            max: self.max,
            base: self.base,
            quantum: self.quantum,
            level_errors: self.level_errors.clone(),
            heights: self.vertices[..grid]
                .iter()
                .map(|v| (v.position[1] - self.base) as u16)
                .collect(),
            texture_size: self.texture_size(),
            first_mip: self.texture_base,
            texture_mips,
            apron: self.apron.clone(),
        }
    }

    /// Keeps only the first `levels` progressive levels (clamped to `1 ..= self.levels`),
    /// geometry and texture, exactly as a tile loaded with those levels: what the pager does to
    /// a far tile under memory pressure before it drops whole tiles. Returns the bytes held now.
    pub fn drop_levels(&mut self, levels: usize) -> usize {
        if levels < self.levels && !self.absent {
            *self = self.rebuilt(&self.to_tile().truncated(levels), self.light.as_ref());
        }
        self.bytes()
    }

    /// Lights the vertices with `light`, or drops the normals and shades and whitens them
    /// (`None`), exactly as if the tile had been loaded so: switching needs no fetch. Returns
    /// the bytes the tile holds now.
    pub fn set_light(&mut self, light: Option<&Light>) -> usize {
        if self.absent {
            self.light = light.copied();
        } else if self.light.as_ref() != light {
            *self = self.rebuilt(&self.to_tile(), light);
        }
        self.bytes()
    }

    /// `tile`, a form of this tile's own, made resident as this one is (level, texture, crack
    /// mode and extent) under `light`.
    fn rebuilt(&self, tile: &Tile, light: Option<&Light>) -> ResidentTile {
        let cracks = if self.vertices.len() > self.grid() {
            CrackMode::Skirts
        } else {
            CrackMode::None
        };
        ResidentTile::of_level(
            tile,
            self.scale.trailing_zeros() as u8,
            self.texture_base,
            self.spacing,
            light,
            cracks,
        )
        .clipped(self.extent)
    }

    /// Vertices of the held grid, before the crack mode's extra ones.
    fn grid(&self) -> usize {
        if self.absent { 0 } else { self.side().pow(2) }
    }

    /// Texels per side of the archive's finest texture mip (held or not).
    fn texture_size(&self) -> usize {
        (self.texture.levels()[0].width() as usize) << self.texture_base
    }

    /// Bytes this tile holds: what the memory limit accounts.
    pub fn bytes(&self) -> usize {
        let shades: usize = self.coarse_shades.iter().map(Vec::len).sum();
        resident_bytes(
            self.vertices.len(),
            self.normals.len(),
            self.level_errors.len(),
            self.texture.byte_size() + self.apron.bytes() + shades,
        )
    }

    /// The vertices to draw mask `mask_level` (a whole-tile level the tile can draw) with,
    /// lit from the grid that mask needs: [`Self::vertices`] when that is the held grid or the
    /// tile is unlit, else
    /// `scratch`, as long as the vertices, holding every sample of that grid and the skirt
    /// vertices under its border samples, coloured by [`Self::coarse_shades`]. Its other
    /// entries are left as they were: neither the draw nor the geomorph reads them (a morph
    /// of the mask's samples needs only their ancestors, which lie on that grid too: the
    /// geomorph's tests check it), so no copy of the whole tile is paid.
    pub fn lit_vertices<'v>(
        &'v self,
        mask_level: usize,
        scratch: &'v mut Vec<Vertex>,
    ) -> &'v [Vertex] {
        let level = levels_for_mask(mask_level, progressive_levels(self.tile_size)) - 1;
        if level + 1 >= self.levels || self.light.is_none() {
            return &self.vertices;
        }
        let (side, grid) = (self.side(), self.grid());
        scratch.resize(self.vertices.len(), Vertex::default());
        scratch[grid..].copy_from_slice(&self.vertices[grid..]);
        let (n, step) = (level_side(level), 1 << (self.levels - 1 - level));
        for (k, &c) in self.coarse_shades[level].iter().enumerate() {
            let at = (k / n) * step * side + (k % n) * step;
            scratch[at] = Vertex {
                color: [c; 3],
                ..self.vertices[at]
            };
        }
        if self.vertices.len() > grid {
            skirts::copy_border_colors(scratch, side, step);
        }
        scratch
    }

    /// Adds or removes the skirt vertices so that the tile draws in crack mode `cracks` (heights
    /// in archive quanta of `quantum` metres), exactly as if it had been loaded in that mode:
    /// switching modes needs no fetch. Returns the bytes the tile holds now.
    pub fn set_cracks(&mut self, cracks: CrackMode, quantum: f32) -> usize {
        if self.absent {
            return self.bytes();
        }
        let grid = self.grid();
        let s = self.side();
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

/// The bytes a resident tile of `tile_size` samples holding its first `levels` progressive
/// levels holds with its texture from mip `base` of a `texture_size` RGB565 chain (never finer
/// than those levels carry), drawn in crack mode `cracks`, `lit` or not, known before the tile
/// is fetched.
pub fn predicted_bytes(
    tile_size: usize,
    texture_size: usize,
    base: usize,
    levels: usize,
    cracks: CrackMode,
    lit: bool,
) -> usize {
    let levels = levels.clamp(1, progressive_levels(tile_size));
    let first = level_mips(levels - 1, tile_size, texture_size).start;
    let base = base.max(first).min(mip_count(texture_size) - 1);
    let texels: usize = (base..mip_count(texture_size))
        .map(|l| (texture_size >> l).pow(2))
        .sum();
    let side = level_side(levels - 1);
    let grid = side * side;
    let apron: usize = (0..levels).map(|g| Apron::level_len(level_side(g))).sum();
    let shades: usize = (0..levels - 1).map(|g| level_side(g).pow(2)).sum();
    let (normals, shades) = if lit { (grid, shades) } else { (0, 0) };
    resident_bytes(
        grid + cracks.extra_vertices(side),
        normals,
        tile_size - 1,
        2 * texels + apron * std::mem::size_of::<i16>() + shades,
    )
}

/// What a resident tile holds: its struct, vertices, normals, level errors, and the bytes of
/// its texture, apron and coarser levels' shades.
fn resident_bytes(vertices: usize, normals: usize, levels: usize, other_bytes: usize) -> usize {
    std::mem::size_of::<ResidentTile>()
        + vertices * std::mem::size_of::<Vertex>()
        + normals * std::mem::size_of::<[i8; 3]>()
        + levels * std::mem::size_of::<f32>()
        + other_bytes
}

/// Unit normals of held progressive level `level`'s grid from central differences, `spacing`
/// metres between its samples; across the tile border the other side is that level's apron.
fn normals(tile: &Tile, level: usize, spacing: f64) -> Vec<[i8; 3]> {
    let s = level_side(level);
    let slopes = SlopeNormals::new(tile.quantum, spacing);
    // The level's heights framed by its apron, each read once (a sample's four neighbours are
    // then loads); the frame's corners are never read.
    let w = s + 2;
    let mut framed = vec![0; w * w];
    for j in -1..=s as isize {
        for i in -1..=s as isize {
            let corner = (i == -1 || i == s as isize) && (j == -1 || j == s as isize);
            if !corner {
                framed[(j + 1) as usize * w + (i + 1) as usize] = tile.quanta_around(level, i, j);
            }
        }
    }
    // Row by row, not `k / s` per sample: a library call on a core without a divider.
    (0..s)
        .flat_map(|j| (j + 1) * w + 1..(j + 1) * w + 1 + s)
        .map(|at| {
            slopes.packed(
                framed[at - 1],
                framed[at + 1],
                framed[at - w],
                framed[at + w],
            )
        })
        .collect()
}

/// The texture chain of `tile` from archive mip `base` (one the tile holds) down.
fn chain_from(tile: &Tile, base: usize) -> Texture {
    let t = tile.texture_size;
    let levels = tile.texture_mips[base - tile.first_mip..]
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
    use glam::DVec3;

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
        let r = ResidentTile::new(&tile, 0, 2.0, Some(&Light::default()), CrackMode::None);
        assert_eq!(r.vertices.len(), 81);
        let v = r.vertices[2 * 9 + 3];
        assert_eq!(v.position, [3, tile.quanta(3, 2), 2]);
        assert_eq!(tile.quanta(3, 2), 96);
        // Texel u of 8 shows the point u * 8 / 7: the point 3 is at texel 21 / 8.
        let texel = |x: f32| (0.5 + x * 7.0 / 8.0) / 8.0;
        assert_eq!(v.uv.map(|c| c.to_num::<f32>()), [texel(3.0), texel(2.0)]);
    }

    #[test]
    fn normals_follow_the_slope_and_light_follows_the_normals() {
        let tile = sloped_tile();
        // A 45° slope facing west: the normal is (-1, 1, 0) / sqrt 2.
        let r = ResidentTile::new(&tile, 0, 2.0, Some(&Light::default()), CrackMode::None);
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
        let lit =
            ResidentTile::new(&tile, 0, 2.0, Some(&west), CrackMode::None).vertices[40].color[0];
        let dark =
            ResidentTile::new(&tile, 0, 2.0, Some(&east), CrackMode::None).vertices[40].color[0];
        assert_eq!(lit, 255);
        assert_eq!(dark, (0.2f64 * 255.0).round() as u8);
    }

    #[test]
    fn accounted_bytes_are_known_before_loading_and_shrink_with_the_texture() {
        let tile = sloped_tile();
        for base in 0..5 {
            for cracks in CrackMode::ALL {
                let r = ResidentTile::new(&tile, base, 2.0, Some(&Light::default()), cracks);
                assert_eq!(
                    r.bytes(),
                    predicted_bytes(9, 8, base, 4, cracks, true),
                    "{cracks:?}"
                );
            }
        }
        let skirted = ResidentTile::new(&tile, 0, 2.0, Some(&Light::default()), CrackMode::Skirts);
        for from in CrackMode::ALL {
            for to in CrackMode::ALL {
                let mut r = ResidentTile::new(&tile, 1, 2.0, Some(&Light::default()), from);
                let fresh = ResidentTile::new(&tile, 1, 2.0, Some(&Light::default()), to);
                assert_eq!(
                    r.set_cracks(to, tile.quantum),
                    fresh.bytes(),
                    "{from:?} -> {to:?}"
                );
                assert_eq!(r.vertices, fresh.vertices, "{from:?} -> {to:?}");
            }
        }
        assert_eq!(skirted.vertices.len(), 81 + 36);
        let mut r = ResidentTile::new(&tile, 0, 2.0, Some(&Light::default()), CrackMode::None);
        let full = r.bytes();
        assert_eq!(r.texture.levels().len(), 4);
        let smaller = r.coarsen_texture(2);
        assert_eq!(r.texture_base, 2);
        assert_eq!(r.texture.levels()[0].width(), 2);
        assert_eq!(smaller, predicted_bytes(9, 8, 2, 4, CrackMode::None, true));
        assert_eq!(full - smaller, 2 * (64 + 16));
        assert_eq!(r.coarsen_texture(1), smaller, "never refines");
    }

    #[test]
    fn an_unlit_tile_holds_no_lighting_and_lighting_it_is_loading_it_lit() {
        let tile = rough_tile();
        let light = Light::default();
        for cracks in [CrackMode::Stitch, CrackMode::Skirts] {
            for levels in 1..=tile.levels {
                let t = tile.truncated(levels);
                let lit = ResidentTile::of_level(&t, 1, 0, 2.0, Some(&light), cracks);
                let unlit = ResidentTile::of_level(&t, 1, 0, 2.0, None, cracks);
                assert!(unlit.normals.is_empty() && unlit.coarse_shades.is_empty());
                for (u, l) in unlit.vertices.iter().zip(&lit.vertices) {
                    assert_eq!((u.position, u.uv), (l.position, l.uv));
                    assert_eq!(u.color, [255; 3]);
                }
                assert_eq!(
                    unlit.bytes(),
                    predicted_bytes(17, 16, 0, levels, cracks, false)
                );
                assert!(unlit.bytes() < lit.bytes());
                let mut scratch = Vec::new();
                for mask in 0..=unlit.finest_mask_level() {
                    let drawn = unlit.lit_vertices(mask, &mut scratch);
                    assert_eq!(drawn, &unlit.vertices[..], "unlit draws as held");
                }
                let (mut lighted, mut unlighted) = (unlit.clone(), lit.clone());
                assert_eq!(lighted.set_light(Some(&light)), lit.bytes());
                assert_eq!(unlighted.set_light(None), unlit.bytes());
                for (a, b) in [(&lighted, &lit), (&unlighted, &unlit)] {
                    assert_eq!(a.vertices, b.vertices, "{levels} levels, {cracks:?}");
                    assert_eq!(a.normals, b.normals);
                    assert_eq!(a.coarse_shades, b.coarse_shades);
                    assert_eq!(a.light, b.light);
                }
            }
        }
        let mut absent = ResidentTile::absent(17, 0, 2.0, None);
        let bytes = absent.bytes();
        assert_eq!(absent.set_light(Some(&light)), bytes);
        assert_eq!(absent.light, Some(light));
    }

    /// A 17-sample tile with rough relief and a texture whose every mip differs.
    fn rough_tile() -> Tile {
        let s = 17;
        let heights: Vec<f32> = (0..s * s)
            .map(|k| 30.0 * ((k % s) as f32 * 1.3).sin() + 20.0 * ((k / s) as f32 * 0.7).cos())
            .collect();
        let texture: Vec<[u8; 3]> = (0..256)
            .map(|k| {
                [
                    (k * 7 % 256) as u8,
                    (k * 13 % 256) as u8,
                    (k % 16 * 16) as u8,
                ]
            })
            .collect();
        Tile::new(&heights, s, 0.125, &texture, 16).unwrap()
    }

    #[test]
    fn a_partial_tile_holds_a_compact_grid_in_whole_tile_units() {
        let tile = rough_tile();
        let coarse = tile.truncated(3);
        let r = ResidentTile::new(&coarse, 0, 2.0, Some(&Light::default()), CrackMode::Skirts);
        assert_eq!((r.side(), r.stride(), r.finest_mask_level()), (5, 4, 3));
        assert_eq!(r.normals.len(), 25);
        assert_eq!(r.vertices.len(), 25 + 4 * 5);
        let v = r.vertices[2 * 5 + 3];
        assert_eq!(v.position, [12, tile.quanta(12, 8), 8]);
        let texel = |x: f32| (0.5 + x * 15.0 / 16.0) / 16.0;
        assert_eq!(v.uv.map(|c| c.to_num::<f32>()), [texel(12.0), texel(8.0)]);
        assert_eq!(
            r.texture_base, coarse.first_mip,
            "never finer than it holds"
        );
        assert!(!r.is_complete());
    }

    #[test]
    fn the_resident_form_gives_back_the_tile_it_was_built_from() {
        let tile = rough_tile();
        for levels in 1..=tile.levels {
            let t = tile.truncated(levels);
            for cracks in CrackMode::ALL {
                let r = ResidentTile::new(&t, t.first_mip, 2.0, Some(&Light::default()), cracks);
                assert_eq!(r.to_tile(), t, "{levels} levels, {cracks:?}");
            }
        }
    }

    #[test]
    fn bytes_shrink_with_fewer_levels_and_are_known_before_loading() {
        let tile = rough_tile();
        for cracks in CrackMode::ALL {
            let mut previous = usize::MAX;
            for levels in (1..=tile.levels).rev() {
                let t = tile.truncated(levels);
                for base in 0..6 {
                    let r = ResidentTile::new(&t, base, 2.0, Some(&Light::default()), cracks);
                    assert_eq!(
                        r.bytes(),
                        predicted_bytes(17, 16, base, levels, cracks, true),
                        "{levels} levels, base {base}, {cracks:?}"
                    );
                }
                let bytes = predicted_bytes(17, 16, 0, levels, cracks, true);
                assert!(bytes < previous, "{levels} levels, {cracks:?}");
                previous = bytes;
            }
        }
    }

    #[test]
    fn dropping_levels_is_loading_fewer() {
        let tile = rough_tile();
        let light = Light::default();
        for cracks in [CrackMode::Stitch, CrackMode::Skirts] {
            for base in [0, 3] {
                for levels in 1..=tile.levels {
                    let mut r = ResidentTile::new(&tile, base, 2.0, Some(&light), cracks);
                    let fresh =
                        ResidentTile::new(&tile.truncated(levels), base, 2.0, Some(&light), cracks);
                    assert_eq!(r.drop_levels(levels), fresh.bytes());
                    assert_eq!(r.vertices, fresh.vertices, "{levels} levels, {cracks:?}");
                    assert_eq!(r.normals, fresh.normals);
                    assert_eq!(r.texture, fresh.texture);
                    assert_eq!(
                        (r.texture_base, r.levels),
                        (fresh.texture_base, fresh.levels)
                    );
                    assert_eq!(r.drop_levels(tile.levels), fresh.bytes(), "never refines");
                }
            }
        }
    }

    #[test]
    fn a_refined_tile_is_the_tile_loaded_with_its_levels() {
        let tile = rough_tile().with_apron(|i, j| Some(12.0 * ((i * 3 + j * 5) as f32).sin()));
        let (light, cracks) = (Light::default(), CrackMode::Skirts);
        let load =
            |t: &Tile, light: &Light| ResidentTile::of_level(t, 1, 0, 2.0, Some(light), cracks);
        let same = |a: &ResidentTile, b: &ResidentTile, why: &str| {
            assert_eq!(a.vertices, b.vertices, "{why}");
            assert_eq!(a.normals, b.normals, "{why}");
            assert_eq!(a.coarse_shades, b.coarse_shades, "{why}");
        };
        for held in 1..=tile.levels {
            let before = load(&tile.truncated(held), &light);
            for levels in held..=tile.levels {
                let t = tile.truncated(levels);
                let refined = ResidentTile::refined(&before, &t, 1, 0, 2.0, Some(&light), cracks);
                same(&refined, &load(&t, &light), &format!("{held} to {levels}"));
            }
        }
        let other = Light {
            direction: DVec3::new(1.0, 1.0, 0.0),
            ambient: 0.1,
        };
        let before = load(&tile.truncated(2), &light);
        let relit = ResidentTile::refined(&before, &tile, 1, 0, 2.0, Some(&other), cracks);
        same(
            &relit,
            &load(&tile, &other),
            "another light lights every level",
        );
        let unlit = |t: &Tile| ResidentTile::of_level(t, 1, 0, 2.0, None, cracks);
        let before = unlit(&tile.truncated(2));
        let lit = ResidentTile::refined(&before, &tile, 1, 0, 2.0, Some(&light), cracks);
        same(
            &lit,
            &load(&tile, &light),
            "a light lights every level of an unlit tile",
        );
        let before = load(&tile.truncated(2), &light);
        let dark = ResidentTile::refined(&before, &tile, 1, 0, 2.0, None, cracks);
        same(&dark, &unlit(&tile), "no light keeps no shade");
    }

    #[test]
    fn a_tile_drawn_at_a_level_is_lit_like_the_tile_holding_only_that_level() {
        let tile = rough_tile();
        let light = Light::default();
        for cracks in [CrackMode::Stitch, CrackMode::Skirts] {
            for held in 1..=tile.levels {
                let r = ResidentTile::new(&tile.truncated(held), 0, 2.0, Some(&light), cracks);
                for levels in 1..=held {
                    let only =
                        ResidentTile::new(&tile.truncated(levels), 0, 2.0, Some(&light), cracks);
                    let mask = only.finest_mask_level();
                    let mut scratch = Vec::new();
                    let lit = r.lit_vertices(mask, &mut scratch).to_vec();
                    let (side, step) = (only.side(), only.stride() / r.stride());
                    for (k, v) in only.vertices[..side * side].iter().enumerate() {
                        let at = (k / side) * step * r.side() + (k % side) * step;
                        assert_eq!(lit[at], *v, "{held} held, drawn with {levels}, {cracks:?}");
                    }
                    let (skirt, only_skirt) = (r.side().pow(2), side * side);
                    for (k, v) in only.vertices[only_skirt..].iter().enumerate() {
                        let (border, t) = (k / side, k % side);
                        assert_eq!(lit[skirt + border * r.side() + t * step], *v);
                    }
                    if levels == held {
                        assert_eq!(lit, r.vertices, "its own vertices at its finest level");
                    } else {
                        let own =
                            |k: usize| r.vertices[(k / side) * step * r.side() + (k % side) * step];
                        assert!(
                            (0..side * side).any(|k| own(k).color != only.vertices[k].color),
                            "a coarser grid lights differently: {held} held, {levels} drawn"
                        );
                    }
                }
            }
        }
    }
}
