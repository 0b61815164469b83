//! Crack hiding: what fills the gaps that open between neighbouring tiles drawn at different
//! strip-mask levels.
//!
//! A mask level keeps a subset of each border's samples, so where a fine tile meets a coarse one
//! the fine tile's border vertices (T-junctions) lie above or below the coarse tile's border
//! segment and the background shows through. [`CrackMode`] chooses the remedy:
//!
//! - [`CrackMode::Stitch`] (`stitch`): crack-free by construction. A tile is drawn as an
//!   interior plus four border bands chosen by its neighbours' levels, so that both tiles of a
//!   shared border use the same edge vertices.
//! - [`CrackMode::Skirts`] (`skirts`): a band of vertical triangles hanging from each border.
//! - [`CrackMode::Shadow`] (`shadow`): the paper's planar shadow under each tile, projected
//!   from the viewpoint.

pub mod neighbours;
pub(crate) mod shadow;
pub(crate) mod skirts;
mod stitch;

#[cfg(test)]
mod test_view;

use stripmask_raster::{Indices, Topology};

use crate::engine::masks::{MaskIndices, MaskSet};
use crate::named::named_enum;
use skirts::SkirtSet;
use stitch::StitchSet;

/// How the gaps between tiles at different levels are hidden. The default is the best
/// measured (`docs/cracks.md`): [`CrackMode::Stitch`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum CrackMode {
    /// Nothing: cracks show.
    None,
    /// The paper's planar shadow quad under each tile.
    Shadow,
    /// Vertical skirts hanging from the tile borders.
    Skirts,
    /// Border bands that match the neighbours' levels: no crack at all.
    #[default]
    Stitch,
}

/// A side of a tile: north is row `j = 0`, west is column `i = 0`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Side {
    /// Row 0.
    North,
    /// Column `s - 1`.
    East,
    /// Row `s - 1`.
    South,
    /// Column 0.
    West,
}

named_enum!(CrackMode, "crack mode", {
    None => "none",
    Shadow => "shadow",
    Skirts => "skirts",
    Stitch => "stitch",
});

impl CrackMode {
    /// Every mode, in the order the viewer's K key cycles through them.
    pub const ALL: [CrackMode; 4] = [
        CrackMode::None,
        CrackMode::Shadow,
        CrackMode::Skirts,
        CrackMode::Stitch,
    ];

    /// The mode after this one in [`CrackMode::ALL`], wrapping around.
    pub fn next(self) -> CrackMode {
        let k = CrackMode::ALL.iter().position(|&m| m == self).unwrap_or(0);
        CrackMode::ALL[(k + 1) % CrackMode::ALL.len()]
    }

    /// Vertices a tile of `tile_size` samples per side holds beyond its grid in this mode.
    pub fn extra_vertices(self, tile_size: usize) -> usize {
        match self {
            CrackMode::Skirts => skirts::vertex_count(tile_size),
            CrackMode::None | CrackMode::Shadow | CrackMode::Stitch => 0,
        }
    }
}

impl Side {
    /// The four sides, in the order of a tile's neighbour levels.
    pub const ALL: [Side; 4] = [Side::North, Side::East, Side::South, Side::West];
}

/// The index buffers a crack mode draws tiles with, and the scratch it assembles them in.
#[derive(Debug)]
pub struct TileIndices {
    mode: CrackMode,
    stitch: StitchSet,
    skirts: SkirtSet,
    /// One tile's stitched triangle list, rebuilt for every stitched tile and reused.
    scratch: MaskIndices,
}

impl TileIndices {
    /// The index buffers of `mode` for tiles of `tile_size` samples per side.
    pub fn new(mode: CrackMode, tile_size: usize) -> TileIndices {
        let stitch = StitchSet::new(tile_size);
        TileIndices {
            mode,
            scratch: stitch.buffer(),
            stitch,
            skirts: SkirtSet::new(tile_size),
        }
    }

    /// The crack mode.
    pub fn mode(&self) -> CrackMode {
        self.mode
    }

    /// The indices and topology that draw a tile at `level` whose neighbours are drawn at
    /// `neighbours` ([`Side::ALL`] order) this frame.
    pub fn tile<'a>(
        &'a mut self,
        masks: &'a MaskSet,
        level: usize,
        neighbours: [usize; 4],
    ) -> (Indices<'a>, Topology) {
        match self.mode {
            CrackMode::Stitch => {
                self.stitch.tile(level, neighbours, &mut self.scratch);
                (self.scratch.as_indices(), Topology::TriangleList)
            }
            CrackMode::Skirts => (
                self.skirts.indices(masks, level).as_indices(),
                Topology::TriangleStrip,
            ),
            CrackMode::None | CrackMode::Shadow => {
                (masks.indices(level).as_indices(), Topology::TriangleStrip)
            }
        }
    }
}

/// Appends `piece` to `out`; both have the width of the same tile size.
fn extend(out: &mut MaskIndices, piece: &MaskIndices) {
    match (out, piece) {
        (MaskIndices::U16(o), MaskIndices::U16(p)) => o.extend_from_slice(p),
        (MaskIndices::U32(o), MaskIndices::U32(p)) => o.extend_from_slice(p),
        _ => unreachable!("pieces of one tile size share one index width"),
    }
}

/// Empties `out`, keeping its allocation.
fn clear(out: &mut MaskIndices) {
    match out {
        MaskIndices::U16(o) => o.clear(),
        MaskIndices::U32(o) => o.clear(),
    }
}
