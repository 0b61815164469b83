//! The index buffers of partial tiles: strip masks and crack pieces per held grid side.
//!
//! A tile that holds only its first progressive levels keeps every `stride`-th sample of the
//! whole tile in a compact `side x side` vertex grid ([`crate::engine::resident::ResidentTile`]). Whole-
//! tile mask level `l` with `l + 1` a multiple of the stride keeps exactly the samples that
//! compact level `(l + 1) / stride - 1` keeps on the compact grid (both keep the multiples of
//! `l + 1` and the last row and column), in the same strip order, so the compact masks draw the
//! same triangles. One [`MaskSet`] and one [`TileIndices`] per side serve every partial tile of
//! that side; they are built the first time a tile of that side is drawn, so a terrain whose
//! tiles are all whole pays nothing.

use crate::engine::cracks::{CrackMode, TileIndices};
use crate::engine::masks::{LevelSet, MaskSet};

/// The compact mask level that draws whole-tile mask level `level` on a grid holding every
/// `stride`-th sample: `(level + 1) / stride - 1`. Used for a tile's own level (callers keep
/// `level + 1` a multiple of the stride) and for its neighbours' levels, where a neighbour
/// finer than the held grid counts as the finest held level: the finer neighbour adapts its
/// border to this tile's.
pub fn compact_level(level: usize, stride: usize) -> usize {
    ((level + 1) / stride).max(1) - 1
}

/// The strip masks and crack pieces of every held side drawn so far, for one crack mode.
#[derive(Debug, Default)]
pub struct PartialMeshes {
    mode: Option<CrackMode>,
    /// `(side, masks, crack pieces)`, at most one entry per progressive level.
    sides: Vec<(usize, MaskSet, TileIndices)>,
}

impl PartialMeshes {
    /// An empty set: nothing is built until a partial tile is drawn.
    pub fn new() -> PartialMeshes {
        PartialMeshes::default()
    }

    /// The masks and crack pieces (crack mode `mode`) of tiles holding `side` samples per side,
    /// built on first use. A change of crack mode drops what was built for the previous one.
    pub fn get(&mut self, mode: CrackMode, side: usize) -> (&MaskSet, &mut TileIndices) {
        if self.mode != Some(mode) {
            self.mode = Some(mode);
            self.sides.clear();
        }
        let k = match self.sides.iter().position(|(s, _, _)| *s == side) {
            Some(k) => k,
            None => {
                self.sides.push((
                    side,
                    MaskSet::new(side, LevelSet::All),
                    TileIndices::new(mode, side),
                ));
                self.sides.len() - 1
            }
        };
        let (_, masks, cracks) = &mut self.sides[k];
        (masks, cracks)
    }

    /// The sides built so far.
    pub fn sides(&self) -> impl Iterator<Item = usize> + '_ {
        self.sides.iter().map(|(s, _, _)| *s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::db::mask_level::kept_indices;
    use stripmask_raster::Indices;

    #[test]
    fn compact_levels_keep_the_same_whole_tile_samples() {
        let s = 33;
        for stride in [1, 2, 4, 8, 16, 32] {
            let side = (s - 1) / stride + 1;
            for level in (0..s - 1).filter(|l| (l + 1) % stride == 0) {
                let compact: Vec<usize> = kept_indices(side, compact_level(level, stride))
                    .into_iter()
                    .map(|c| c * stride)
                    .collect();
                assert_eq!(compact, kept_indices(s, level), "stride {stride}, {level}");
            }
        }
        assert_eq!(
            compact_level(0, 4),
            0,
            "a finer neighbour counts as the finest held"
        );
        assert_eq!(compact_level(1, 4), 0);
        assert_eq!(compact_level(15, 4), 3);
    }

    #[test]
    fn sides_are_built_on_first_use_and_per_crack_mode() {
        let mut held = PartialMeshes::new();
        assert_eq!(held.sides().count(), 0);
        let (masks, cracks) = held.get(CrackMode::Stitch, 5);
        assert_eq!(masks.tile_size(), 5);
        assert_eq!(cracks.mode(), CrackMode::Stitch);
        let (indices, _) = cracks.tile(masks, 0, [0; 4]);
        assert!(matches!(indices, Indices::U16(i) if i.len() == 3 * 2 * 4 * 4));
        held.get(CrackMode::Stitch, 3);
        held.get(CrackMode::Stitch, 5);
        assert_eq!(held.sides().collect::<Vec<_>>(), [5, 3]);
        let (_, cracks) = held.get(CrackMode::Skirts, 3);
        assert_eq!(cracks.mode(), CrackMode::Skirts);
        assert_eq!(held.sides().collect::<Vec<_>>(), [3]);
    }
}
