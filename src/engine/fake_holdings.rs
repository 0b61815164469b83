//! Resident tiles without an archive, for the tests of what reads them (the cut, the frame's
//! plan): a holding of small tiles that all span heights 0 to 100 m over a terrain of any size.

use crate::db::archive::Header;
use crate::db::grid::{Pyramid, TileId, TileMap};
use crate::db::tile::Tile;
use crate::engine::cracks::CrackMode;
use crate::engine::cut::Holdings;
use crate::engine::resident::ResidentTile;
use crate::engine::shading::Light;
use crate::engine::terrain::TerrainFrame;

pub(crate) const S: usize = 5;
pub(crate) const SPACING: f64 = 10.0;

/// Resident tiles by id, and how many resident tiles lie under each.
#[derive(Default)]
pub(crate) struct Fake {
    pub(crate) tiles: TileMap<ResidentTile>,
    pub(crate) covered: TileMap<u32>,
}

impl Holdings for Fake {
    fn tile(&self, id: TileId) -> Option<&ResidentTile> {
        self.tiles.get(&id)
    }

    fn covered(&self, id: TileId) -> u32 {
        self.covered.get(&id).copied().unwrap_or(0)
    }
}

/// A tile spanning heights 0 ..= 100 m like every other, so that every box in view at the
/// archive's height range is in view at its own too.
pub(crate) fn tile(id: TileId) -> ResidentTile {
    let mut heights = vec![50.0; S * S];
    (heights[0], heights[S * S - 1]) = (0.0, 100.0);
    let t = Tile::new(&heights, S, 0.25, &[[90, 120, 80]; 16], 4).unwrap();
    ResidentTile::of_level(
        &t,
        id.level,
        0,
        SPACING,
        Some(&Light::default()),
        CrackMode::None,
    )
}

pub(crate) fn terrain(tiles_x: u32, tiles_y: u32) -> TerrainFrame {
    let cells = (S - 1) as u32;
    TerrainFrame::new(&Header {
        tiles_x,
        tiles_y,
        tile_size: S as u32,
        texture_size: 4,
        codec: crate::db::archive::Codec::None,
        source_width: tiles_x * cells + 1,
        source_height: tiles_y * cells + 1,
        spacing: SPACING,
        vertical_scale: 1.0,
        origin_x: 0.0,
        origin_y: 0.0,
        min_height: 0.0,
        max_height: 100.0,
        height_quantum: 0.25,
        nodata_filled: 0,
        nodata_flattened: 0,
        absent_tiles: 0,
        top_level: 0,
        top_offset: 0,
        top_len: 0,
        archive_len: 0,
        georef: None,
    })
}

/// A holding of the resident copies of `ids` in `pyramid`.
pub(crate) fn holding(pyramid: &Pyramid, ids: impl Iterator<Item = TileId>) -> Fake {
    let mut fake = Fake::default();
    for id in ids {
        fake.tiles.insert(id, tile(id));
        for level in id.level + 1..pyramid.levels() as u8 {
            *fake.covered.entry(id.ancestor(level)).or_default() += 1;
        }
    }
    fake
}
