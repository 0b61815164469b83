//! The engine's [`TileLoader`]: fetches a tile from an archive and makes it resident, keeping
//! only the texture detail its belt distance can show.
//!
//! A tile `ring` belts away is at least about `ring - 1/2` tile sides from the eye, so on a screen
//! with focal length `f` pixels its texture of `t` texels spans at most `f / ring` pixels: mips
//! finer than that would never be sampled. The loader keeps mips from
//! `floor(log2(t · ring / f))` down — far tiles never hold full-resolution texels — and the pager
//! shrinks a tile (drops mips) when the viewer moves away, or fetches it again when the viewer
//! comes back.
//!
//! A texture memory budget coarsens that rule by a whole number of mip levels (the *bias*): the
//! smallest bias with which the textures of the largest square of belts the memory limit allows
//! fit the budget. It is decided once, before anything is fetched, so the pager's accounting
//! stays exact.

use std::sync::atomic::{AtomicBool, AtomicU8, AtomicUsize, Ordering};

use crate::db::archive::ArchiveReader;
use crate::db::grid::TileId;
use crate::db::rgb565::mip_count;
use crate::db::source::{CancelToken, TileSource};
use crate::db::tile::Tile;
use crate::db::tile::progressive_levels;
use crate::engine::cracks::CrackMode;
use crate::engine::paging::stream::LevelLoader;
use crate::engine::paging::{ResidentLoader, TileLoader};
use crate::engine::resident::{ResidentTile, predicted_bytes};
use crate::engine::shading::Light;
use crate::engine::terrain::TerrainFrame;
use crate::error::{Error, Result};

/// Loads resident tiles from an archive.
///
/// The crack mode, the lighting and the texture bias can change while the fetch thread loads
/// tiles ([`ArchiveLoader::set_cracks`], [`ArchiveLoader::set_lit`]), so they are atomics; a
/// tile loaded under the old ones is brought up to date by [`TileLoader::refit`] when it
/// arrives.
pub struct ArchiveLoader {
    reader: ArchiveReader<Box<dyn TileSource>>,
    light: Light,
    /// Whether tiles are lit by `light`, or held unlit (no normals, white vertices).
    lit: AtomicBool,
    needed_mips: NeededMips,
    /// Index into [`CrackMode::ALL`].
    cracks: AtomicU8,
    bias: AtomicUsize,
    /// The memory limit and texture budget the bias was fitted to, if any.
    texture_fit: Option<(usize, usize)>,
    /// The finest pyramid level of the archive's top kept resident; `None`: no top.
    top_level: Option<u8>,
    /// Where the archive's tiles lie.
    terrain: TerrainFrame,
}

impl ArchiveLoader {
    /// A loader over `reader`, lighting with `light` when `lit`, for a screen whose focal
    /// length is `focal_px` pixels (height / (2 tan(fov_y / 2))), with the vertices crack mode
    /// `cracks` draws.
    pub fn new(
        reader: ArchiveReader<Box<dyn TileSource>>,
        (light, lit): (Light, bool),
        focal_px: f64,
        cracks: CrackMode,
    ) -> Self {
        let terrain = TerrainFrame::new(reader.header());
        let h = reader.header();
        let needed_mips = NeededMips::new(
            h.texture_size as usize,
            focal_px.max(1.0),
            h.tiles_x.max(h.tiles_y),
        );
        ArchiveLoader {
            reader,
            light,
            lit: AtomicBool::new(lit),
            needed_mips,
            cracks: AtomicU8::new(mode_index(cracks)),
            bias: AtomicUsize::new(0),
            texture_fit: None,
            top_level: None,
            terrain,
        }
    }

    /// Keeps the archive's top resident from pyramid level `level` up (no finer than the top
    /// the archive stores; `None`: no top). Returns the finest level kept.
    pub fn use_top(&mut self, level: Option<u8>) -> Option<u8> {
        let stored = self.reader.header().top_level as u8;
        self.top_level = level.map(|l| l.max(stored));
        self.top_level
    }

    /// The finest pyramid level of the top kept resident, if any.
    pub fn top_level(&self) -> Option<u8> {
        self.top_level
    }

    /// Coarsens textures until those of the largest square of belts that fits `memory_limit`
    /// take at most `texture_budget` bytes (or every tile holds only its 1 x 1 mip). Returns
    /// the bias chosen. The square is counted whole (8 d tiles in belt d), as it is away from
    /// the terrain's borders.
    pub fn fit_texture_budget(&mut self, memory_limit: usize, texture_budget: usize) -> usize {
        self.texture_fit = Some((memory_limit, texture_budget));
        let bias = self.fitted_bias(memory_limit, texture_budget);
        self.bias.store(bias, Ordering::Relaxed);
        bias
    }

    /// The crack mode tiles are loaded for.
    pub fn cracks(&self) -> CrackMode {
        CrackMode::ALL[usize::from(self.cracks.load(Ordering::Relaxed))]
    }

    /// Whether tiles are loaded lit.
    pub fn lit(&self) -> bool {
        self.lit.load(Ordering::Relaxed)
    }

    /// The light tiles are loaded under, `None` when unlit.
    fn light(&self) -> Option<&Light> {
        self.lit().then_some(&self.light)
    }

    /// Where tile `id` is cut: the last of its positions east and south that belong to the
    /// model.
    fn extent(&self, id: TileId) -> [i32; 2] {
        self.terrain.tile_extent(id)
    }

    /// The resident form of tile `id` made of `tile` (`None`: absent) with textures from mip
    /// `texture_base`.
    fn resident(&self, id: TileId, tile: Option<&Tile>, texture_base: usize) -> ResidentTile {
        let h = self.reader.header();
        match tile {
            Some(tile) => ResidentTile::of_level(
                tile,
                id.level,
                texture_base,
                h.spacing,
                self.light(),
                self.cracks(),
            )
            .clipped(self.extent(id)),
            None => ResidentTile::absent(h.tile_size as usize, id.level, h.spacing, self.light()),
        }
    }

    /// Loads tiles for crack mode `cracks` from now on (and refits the texture bias to the
    /// budget, whose share of memory depends on the mode's geometry). Tiles already loaded are
    /// brought to the new mode by [`TileLoader::refit`].
    pub fn set_cracks(&self, cracks: CrackMode) {
        self.cracks.store(mode_index(cracks), Ordering::Relaxed);
        self.refit_bias();
    }

    /// Loads tiles lit (`true`) or unlit from now on, and refits the texture bias as
    /// [`ArchiveLoader::set_cracks`] does. Tiles already loaded are relit or unlit by
    /// [`TileLoader::refit`].
    pub fn set_lit(&self, lit: bool) {
        self.lit.store(lit, Ordering::Relaxed);
        self.refit_bias();
    }

    /// Fits the texture bias again to the budget, if one was set, after the geometry's share
    /// of memory changed.
    fn refit_bias(&self) {
        if let Some((memory_limit, texture_budget)) = self.texture_fit {
            let bias = self.fitted_bias(memory_limit, texture_budget);
            self.bias.store(bias, Ordering::Relaxed);
        }
    }

    /// The bytes of a tile of `levels` levels with its texture from mip `base`, as tiles are
    /// loaded now.
    fn bytes_of(&self, base: usize, levels: usize) -> usize {
        let h = self.reader.header();
        let (s, t) = (h.tile_size as usize, h.texture_size as usize);
        predicted_bytes(s, t, base, levels, self.cracks(), self.lit())
    }

    /// The smallest bias with which the textures of the largest square of belts fit the budget.
    fn fitted_bias(&self, memory_limit: usize, texture_budget: usize) -> usize {
        let h = self.reader.header();
        let (s, t) = (h.tile_size as usize, h.texture_size as usize);
        let max_ring = h.tiles_x.max(h.tiles_y);
        // A tile's bytes without any texture: its bytes with only the 1 x 1 RGB565 mip, less it.
        let geometry = self.bytes_of(usize::MAX, progressive_levels(s)) - 2;
        let mut chosen = 0;
        for bias in 0..mip_count(t) {
            chosen = bias;
            let (mut memory, mut texture) = (0usize, 0usize);
            for ring in 0..=max_ring {
                let tiles = if ring == 0 { 1 } else { 8 * ring as usize };
                let tile = self.bytes_of(self.texture_base_with(ring, bias), progressive_levels(s));
                if memory + tiles * tile > memory_limit {
                    break;
                }
                memory += tiles * tile;
                texture += tiles * (tile - geometry);
            }
            if texture <= texture_budget {
                break;
            }
        }
        chosen
    }

    /// The archive.
    pub fn reader(&self) -> &ArchiveReader<Box<dyn TileSource>> {
        &self.reader
    }

    /// The finest texture mip worth holding for a tile `ring` belts away.
    pub fn texture_base(&self, ring: u32) -> usize {
        self.texture_base_with(ring, self.bias.load(Ordering::Relaxed))
    }

    fn texture_base_with(&self, ring: u32, bias: usize) -> usize {
        let t = self.reader.header().texture_size as usize;
        (self.needed_mips.of(ring) + bias).min(mip_count(t) - 1)
    }
}

/// The finest mip of a texture of side `texture_size` worth holding for a tile `ring` belts
/// away, seen with a focal length of `focal_px` pixels: a texel of that mip then covers about a
/// pixel. Capped at the last mip.
fn needed_mip(texture_size: usize, focal_px: f64, ring: u32) -> usize {
    let t = texture_size as f64;
    let needed = (t * f64::from(ring.max(1)) / focal_px).log2().floor();
    (needed.max(0.0) as usize).min(mip_count(texture_size) - 1)
}

/// [`needed_mip`] by ring, worked out once for the rings up to the model's widest square or
/// twice the focal length (beyond which every ring needs the last mip) and on demand past
/// them: on a core without an FPU its `log2` is a library call, which would otherwise run per
/// tile and frame.
struct NeededMips {
    texture_size: usize,
    focal_px: f64,
    by_ring: Vec<u8>,
}

impl NeededMips {
    fn new(texture_size: usize, focal_px: f64, widest: u32) -> Self {
        let rings = widest.min((2.0 * focal_px).ceil() as u32);
        let by_ring = (0..=rings)
            .map(|ring| needed_mip(texture_size, focal_px, ring) as u8)
            .collect();
        NeededMips {
            texture_size,
            focal_px,
            by_ring,
        }
    }

    fn of(&self, ring: u32) -> usize {
        match self.by_ring.get(ring as usize) {
            Some(&mip) => usize::from(mip),
            None => needed_mip(self.texture_size, self.focal_px, ring),
        }
    }
}

fn mode_index(cracks: CrackMode) -> u8 {
    CrackMode::ALL
        .iter()
        .position(|&m| m == cracks)
        .expect("ALL lists every mode") as u8
}

/// Both strategies hold the same resident tiles and share the top.
impl ResidentLoader for ArchiveLoader {
    type Loaded = ResidentTile;

    fn loaded_bytes(&self, tile: &ResidentTile) -> usize {
        tile.bytes()
    }

    /// Every tile of the kept top, whole.
    fn top_bytes(&self) -> usize {
        let Some(level) = self.top_level else {
            return 0;
        };
        let h = self.reader.header();
        let whole = LevelLoader::predicted_bytes(self, h.levels());
        let absent = ResidentTile::absent(h.tile_size as usize, 0, h.spacing, None).bytes();
        self.reader
            .directory()
            .top
            .iter()
            .filter(|(id, _)| id.level >= level)
            .map(|(_, e)| if e.is_absent() { absent } else { whole })
            .sum()
    }

    fn load_top(&self) -> Result<(Vec<(TileId, ResidentTile)>, u64)> {
        let Some(level) = self.top_level else {
            return Ok((Vec::new(), 0));
        };
        let (tiles, stored) = self.reader.top()?;
        let resident = tiles
            .into_iter()
            .filter(|(id, _)| id.level >= level)
            .map(|(id, tile)| (id, self.resident(id, tile.as_ref(), 0)))
            .collect();
        Ok((resident, stored))
    }

    fn index_bytes(&self) -> usize {
        self.reader.index_cache_limit()
    }
}

impl TileLoader for ArchiveLoader {
    fn predicted_bytes(&self, _id: TileId, ring: u32) -> usize {
        let levels = progressive_levels(self.reader.header().tile_size as usize);
        self.bytes_of(self.texture_base(ring), levels)
    }

    fn load(&self, id: TileId, ring: u32) -> Result<(ResidentTile, u64)> {
        let (tile, downloaded) = self.reader.tile_levels(id, self.reader.header().levels())?;
        Ok((
            self.resident(id, tile.as_ref(), self.texture_base(ring)),
            downloaded,
        ))
    }

    fn shrink(&self, tile: &mut ResidentTile, ring: u32) -> usize {
        tile.coarsen_texture(self.texture_base(ring))
    }

    fn refit(&self, tile: &mut ResidentTile, ring: u32) -> usize {
        LevelLoader::refit(self, tile);
        tile.coarsen_texture(self.texture_base(ring))
    }
}

/// Levels of one tile fetched by the stream pager and not yet merged: their raw chunks.
pub struct LevelPiece {
    /// The levels the tile held when they were asked for.
    have: usize,
    /// The raw chunks of levels `have..`, in order.
    chunks: Vec<Vec<u8>>,
    /// The tile is absent: nothing is stored for it.
    absent: bool,
}

/// Progressive streaming: a tile's levels come one range request at a time and merge into the
/// resident tile; its texture is exactly the mips its levels carry (texture detail follows the
/// levels importance asked for, so the belt-distance rule and the texture budget do not apply).
impl LevelLoader for ArchiveLoader {
    type Piece = LevelPiece;

    fn levels(&self) -> usize {
        self.reader.header().levels()
    }

    fn predicted_bytes(&self, levels: usize) -> usize {
        self.bytes_of(0, levels)
    }

    fn fetch(
        &self,
        id: TileId,
        have: usize,
        want: usize,
        cancel: &CancelToken,
    ) -> Result<(LevelPiece, u64)> {
        let read = self
            .reader
            .read_levels_cancellable(id, have..want, cancel)?;
        Ok((
            LevelPiece {
                have,
                chunks: read.chunks,
                absent: read.absent,
            },
            read.stored_bytes,
        ))
    }

    fn merge(
        &self,
        id: TileId,
        held: Option<&ResidentTile>,
        piece: LevelPiece,
    ) -> Result<ResidentTile> {
        let h = self.reader.header();
        let name = format!("{} {id}", self.reader.name());
        if piece.absent {
            return Ok(self.resident(id, None, 0));
        }
        let held_levels = held.map_or(0, |t| t.levels);
        if held_levels != piece.have {
            return Err(Error::invalid(
                &name,
                format!(
                    "levels from {} arrived for a tile holding {held_levels}",
                    piece.have
                ),
            ));
        }
        let Some(resident) = held else {
            let chunks: Vec<&[u8]> = piece.chunks.iter().map(Vec::as_slice).collect();
            let tile = self.reader.decode(&chunks, &name)?;
            return Ok(self.resident(id, Some(&tile), 0));
        };
        let mut tile = resident.to_tile();
        for chunk in &piece.chunks {
            tile.refine(chunk, &name)?;
        }
        debug_assert_eq!(tile.tile_size, h.tile_size as usize);
        let cracks = self.cracks();
        let refined = ResidentTile::refined(
            resident,
            &tile,
            id.level,
            0,
            h.spacing,
            self.light(),
            cracks,
        );
        Ok(refined.clipped(self.extent(id)))
    }

    fn held_levels(&self, tile: &ResidentTile) -> usize {
        tile.levels
    }

    fn is_absent(&self, tile: &ResidentTile) -> bool {
        tile.absent
    }

    fn drop_levels(&self, tile: &mut ResidentTile, levels: usize) -> usize {
        tile.drop_levels(levels)
    }

    fn refit(&self, tile: &mut ResidentTile) -> usize {
        tile.set_light(self.light());
        tile.set_cracks(self.cracks(), self.reader.header().height_quantum)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_needed_mips_by_ring_are_those_worked_out_per_ring() {
        for (texture_size, focal_px, widest) in [
            (64, 207.8, 15),
            (64, 207.8, 10_000),
            (256, 1000.0, 625),
            (33, 1.0, 3),
            (1, 120.0, 0),
            (512, 3000.5, 40_000),
        ] {
            let mips = NeededMips::new(texture_size, focal_px, widest);
            for ring in (0..5000).chain([widest, widest + 1, 1 << 20, u32::MAX]) {
                assert_eq!(
                    mips.of(ring),
                    needed_mip(texture_size, focal_px, ring),
                    "texture {texture_size}, focal {focal_px}, ring {ring}"
                );
            }
        }
    }
}
