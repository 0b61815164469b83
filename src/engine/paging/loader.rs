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

use std::sync::atomic::{AtomicU8, AtomicUsize, Ordering};

use crate::db::archive::ArchiveReader;
use crate::db::grid::TileId;
use crate::db::rgb565::mip_count;
use crate::db::source::{CancelToken, TileSource};
use crate::db::tile::Tile;
use crate::db::tile::progressive_levels;
use crate::engine::cracks::CrackMode;
use crate::engine::paging::stream::LevelLoader;
use crate::engine::paging::{ResidentLoader, TileLoader};
use crate::engine::resident::{Light, ResidentTile, predicted_bytes};
use crate::engine::terrain::TerrainFrame;
use crate::error::{Error, Result};

/// Loads resident tiles from an archive.
///
/// The crack mode and the texture bias can change while the fetch thread loads tiles
/// ([`ArchiveLoader::set_cracks`]), so they are atomics; a tile loaded under the old ones is
/// brought up to date by [`TileLoader::refit`] when it arrives.
pub struct ArchiveLoader {
    reader: ArchiveReader<Box<dyn TileSource>>,
    light: Light,
    focal_px: f64,
    /// Index into [`CrackMode::ALL`].
    cracks: AtomicU8,
    bias: AtomicUsize,
    /// The memory limit and texture budget the bias was fitted to, if any.
    texture_fit: Option<(usize, usize)>,
    /// Levels of the archive's base every tile keeps resident (0: no base).
    base_levels: usize,
}

impl ArchiveLoader {
    /// A loader over `reader`, lighting with `light`, for a screen whose focal length is
    /// `focal_px` pixels (height / (2 tan(fov_y / 2))), with the vertices crack mode `cracks`
    /// draws.
    pub fn new(
        reader: ArchiveReader<Box<dyn TileSource>>,
        light: Light,
        focal_px: f64,
        cracks: CrackMode,
    ) -> Self {
        ArchiveLoader {
            reader,
            light,
            focal_px: focal_px.max(1.0),
            cracks: AtomicU8::new(mode_index(cracks)),
            bias: AtomicUsize::new(0),
            texture_fit: None,
            base_levels: 0,
        }
    }

    /// Keeps the first `levels` levels of the archive's base resident (at most what it stores;
    /// 0: no base). Returns the levels kept.
    pub fn use_base(&mut self, levels: usize) -> usize {
        self.base_levels = levels.min(self.reader.header().base_levels as usize);
        self.base_levels
    }

    /// Coarsens textures until those of the largest square of belts that fits `memory_limit`
    /// take at most `texture_budget` bytes (or every tile holds only its 1 x 1 mip). Returns
    /// the bias chosen. The square is counted whole (8 d tiles in belt d), as it is away from
    /// the terrain's borders.
    pub fn fit_texture_budget(&mut self, memory_limit: usize, texture_budget: usize) -> usize {
        self.texture_fit = Some((memory_limit, texture_budget));
        let bias = self.fitted_bias(self.cracks(), memory_limit, texture_budget);
        self.bias.store(bias, Ordering::Relaxed);
        bias
    }

    /// The crack mode tiles are loaded for.
    pub fn cracks(&self) -> CrackMode {
        CrackMode::ALL[usize::from(self.cracks.load(Ordering::Relaxed))]
    }

    /// Where tile `id` is cut: the last of its samples east and south that belong to the model.
    fn extent(&self, id: TileId) -> [i32; 2] {
        TerrainFrame::new(self.reader.header()).tile_extent(id.x, id.y)
    }

    /// Loads tiles for crack mode `cracks` from now on (and refits the texture bias to the
    /// budget, whose share of memory depends on the mode's geometry). Tiles already loaded are
    /// brought to the new mode by [`TileLoader::refit`].
    pub fn set_cracks(&self, cracks: CrackMode) {
        self.cracks.store(mode_index(cracks), Ordering::Relaxed);
        if let Some((memory_limit, texture_budget)) = self.texture_fit {
            let bias = self.fitted_bias(cracks, memory_limit, texture_budget);
            self.bias.store(bias, Ordering::Relaxed);
        }
    }

    /// The smallest bias with which the textures of the largest square of belts fit the budget.
    fn fitted_bias(&self, cracks: CrackMode, memory_limit: usize, texture_budget: usize) -> usize {
        let h = self.reader.header();
        let (s, t) = (h.tile_size as usize, h.texture_size as usize);
        let max_ring = h.tiles_x.max(h.tiles_y);
        // A tile's bytes without any texture: its bytes with only the 1 x 1 RGB565 mip, less it.
        let geometry = predicted_bytes(s, t, usize::MAX, progressive_levels(s), cracks) - 2;
        let mut chosen = 0;
        for bias in 0..mip_count(t) {
            chosen = bias;
            let (mut memory, mut texture) = (0usize, 0usize);
            for ring in 0..=max_ring {
                let tiles = if ring == 0 { 1 } else { 8 * ring as usize };
                let tile = predicted_bytes(
                    s,
                    t,
                    self.texture_base_with(ring, bias),
                    progressive_levels(s),
                    cracks,
                );
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
        let t = self.reader.header().texture_size as f64;
        let needed = (t * f64::from(ring.max(1)) / self.focal_px).log2().floor();
        (needed.max(0.0) as usize + bias).min(mip_count(t as usize) - 1)
    }
}

fn mode_index(cracks: CrackMode) -> u8 {
    CrackMode::ALL
        .iter()
        .position(|&m| m == cracks)
        .expect("ALL lists every mode") as u8
}

/// Both strategies hold the same resident tiles and share the base.
impl ResidentLoader for ArchiveLoader {
    type Loaded = ResidentTile;

    fn loaded_bytes(&self, tile: &ResidentTile) -> usize {
        tile.bytes()
    }

    /// Every tile at the base's levels.
    fn base_bytes(&self) -> usize {
        match self.base_levels {
            0 => 0,
            levels => {
                self.reader.header().tile_count() * LevelLoader::predicted_bytes(self, levels)
            }
        }
    }

    fn load_base(&self) -> Result<(Vec<(TileId, ResidentTile)>, u64)> {
        if self.base_levels == 0 {
            return Ok((Vec::new(), 0));
        }
        let h = self.reader.header();
        let (tiles, stored) = self.reader.base()?;
        let tiles_x = h.tiles_x as usize;
        let resident = tiles
            .into_iter()
            .enumerate()
            .map(|(i, tile)| {
                let id = TileId::new((i % tiles_x) as u32, (i / tiles_x) as u32);
                let tile = tile.truncated(self.base_levels.min(tile.levels));
                let resident = ResidentTile::new(&tile, 0, h.spacing, &self.light, self.cracks())
                    .clipped(self.extent(id));
                (id, resident)
            })
            .collect();
        Ok((resident, stored))
    }
}

impl TileLoader for ArchiveLoader {
    fn predicted_bytes(&self, _id: TileId, ring: u32) -> usize {
        let h = self.reader.header();
        predicted_bytes(
            h.tile_size as usize,
            h.texture_size as usize,
            self.texture_base(ring),
            progressive_levels(h.tile_size as usize),
            self.cracks(),
        )
    }

    fn load(&self, id: TileId, ring: u32) -> Result<(ResidentTile, u64)> {
        let (x, y) = (id.x as usize, id.y as usize);
        let (tile, downloaded) = self
            .reader
            .tile_levels(x, y, self.reader.header().levels())?;
        let spacing = self.reader.header().spacing;
        Ok((
            ResidentTile::new(
                &tile,
                self.texture_base(ring),
                spacing,
                &self.light,
                self.cracks(),
            )
            .clipped(self.extent(id)),
            downloaded,
        ))
    }

    fn shrink(&self, tile: &mut ResidentTile, ring: u32) -> usize {
        tile.coarsen_texture(self.texture_base(ring))
    }

    fn refit(&self, tile: &mut ResidentTile, ring: u32) -> usize {
        tile.set_cracks(self.cracks(), self.reader.header().height_quantum);
        tile.coarsen_texture(self.texture_base(ring))
    }
}

/// Levels of one tile fetched by the stream pager and not yet merged: their raw chunks.
pub struct LevelPiece {
    /// The levels the tile held when they were asked for.
    have: usize,
    /// The raw chunks of levels `have..`, in order.
    chunks: Vec<Vec<u8>>,
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
        let h = self.reader.header();
        predicted_bytes(
            h.tile_size as usize,
            h.texture_size as usize,
            0,
            levels,
            self.cracks(),
        )
    }

    fn fetch(
        &self,
        id: TileId,
        have: usize,
        want: usize,
        cancel: &CancelToken,
    ) -> Result<(LevelPiece, u64)> {
        let read = self.reader.read_levels_cancellable(
            id.x as usize,
            id.y as usize,
            have..want,
            cancel,
        )?;
        Ok((
            LevelPiece {
                have,
                chunks: read.chunks,
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
        let name = format!("{} tile {id}", self.reader.name());
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
        let tile = match held {
            None => {
                let chunks: Vec<&[u8]> = piece.chunks.iter().map(Vec::as_slice).collect();
                let tile = Tile::from_levels(
                    &chunks,
                    h.tile_size as usize,
                    h.texture_size as usize,
                    &name,
                )?;
                if tile.quantum != h.height_quantum {
                    return Err(Error::invalid(
                        &name,
                        format!(
                            "height quantum {} differs from the archive's {}",
                            tile.quantum, h.height_quantum
                        ),
                    ));
                }
                tile
            }
            Some(resident) => {
                let mut tile = resident.to_tile();
                for chunk in &piece.chunks {
                    tile.refine(chunk, &name)?;
                }
                tile
            }
        };
        Ok(
            ResidentTile::new(&tile, 0, h.spacing, &self.light, self.cracks())
                .clipped(self.extent(id)),
        )
    }

    fn held_levels(&self, tile: &ResidentTile) -> usize {
        tile.levels
    }

    fn drop_levels(&self, tile: &mut ResidentTile, levels: usize) -> usize {
        tile.drop_levels(levels)
    }

    fn refit(&self, tile: &mut ResidentTile) -> usize {
        tile.set_cracks(self.cracks(), self.reader.header().height_quantum)
    }
}
