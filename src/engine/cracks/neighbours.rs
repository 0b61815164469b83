//! What a tile knows of its neighbours at frame time: the levels they are drawn at, counted in
//! its own samples — a neighbour may be a tile of another level of the pyramid — and, for
//! stitching, the levels that make the borders between pyramid levels meet.

use super::Side;
use crate::db::grid::{TileId, TileMap};

/// The tile across `side` of `id`, of `id`'s level, if its column and row are not negative.
fn across(id: TileId, side: Side) -> Option<TileId> {
    let (dx, dy) = match side {
        Side::North => (0, -1),
        Side::East => (1, 0),
        Side::South => (0, 1),
        Side::West => (-1, 0),
    };
    let x = id.x.checked_add_signed(dx)?;
    let y = id.y.checked_add_signed(dy)?;
    Some(TileId::at(id.level, x, y))
}

/// Who borders whom among a frame's drawn tiles, found once per frame (the levels they are
/// drawn at change as the budget is shared, their places do not): for each tile and side, the
/// drawn tile across it of its pyramid level or a coarser one, with how many levels coarser.
#[derive(Clone, Debug, Default)]
pub struct Neighbourhood {
    across: Vec<[Option<(usize, u8)>; 4]>,
}

impl Neighbourhood {
    /// The neighbourhood of the drawn tiles `drawn`, in [`Side::ALL`] order per tile. Finer
    /// tiles across a side, or none, leave it `None`.
    pub fn of(drawn: &[TileId]) -> Neighbourhood {
        let index: TileMap<usize> = drawn.iter().enumerate().map(|(k, &id)| (id, k)).collect();
        let coarsest = drawn.iter().map(|id| id.level).max().unwrap_or(0);
        let find = |id: TileId, side: Side| {
            let next = across(id, side)?;
            (id.level..=coarsest).find_map(|level| {
                let k = *index.get(&next.ancestor(level))?;
                Some((k, level - id.level))
            })
        };
        Neighbourhood {
            across: drawn
                .iter()
                .map(|&id| Side::ALL.map(|side| find(id, side)))
                .collect(),
        }
    }

    /// The pairs `(finer, coarser, levels between)` of drawn tiles of different pyramid levels
    /// that share a border.
    fn pyramid_pairs(&self) -> impl Iterator<Item = (usize, usize, u8)> + '_ {
        self.across.iter().enumerate().flat_map(|(a, sides)| {
            sides
                .iter()
                .flatten()
                .filter(|&&(_, coarser)| coarser > 0)
                .map(move |&(b, coarser)| (a, b, coarser))
        })
    }
}

/// For each drawn tile (drawn at `levels`, tiles of `tile_size` samples, placed as
/// `neighbourhood` says), the levels of its four neighbours in [`Side::ALL`] order, counted in
/// its own samples: a neighbour of its pyramid level counts with its level; one `d` levels
/// coarser, whose samples are `2^d` of this tile's apart, with the level whose kept samples are
/// its kept samples, `(l + 1) 2^d - 1` (at most the corners-only level); finer neighbours —
/// which match their borders to this tile — and a side where nothing is drawn count as the
/// tile's own level.
pub fn neighbour_levels(
    neighbourhood: &Neighbourhood,
    levels: &[usize],
    tile_size: usize,
) -> Vec<[usize; 4]> {
    let last = tile_size.saturating_sub(2);
    neighbourhood
        .across
        .iter()
        .zip(levels)
        .map(|(sides, &level)| {
            sides.map(|across| match across {
                Some((k, 0)) => levels[k],
                Some((k, coarser)) => (((levels[k] + 1) << coarser) - 1).min(last),
                None => level,
            })
        })
        .collect()
}

/// For each drawn tile, whether it meets a drawn tile of another level of the pyramid across
/// one of its sides (the tiles [`conform`] may change).
pub fn pyramid_borders(neighbourhood: &Neighbourhood) -> Vec<bool> {
    let mut border = vec![false; neighbourhood.across.len()];
    for (a, b, _) in neighbourhood.pyramid_pairs() {
        border[a] = true;
        border[b] = true;
    }
    border
}

/// Makes stitching close the borders between pyramid levels: a tile bordering a finer one
/// keeps that tile's corners (its samples there are `2^d` of the finer tile's apart, so its
/// mask keeps no more than every `(s - 1) / 2^d`-th), and both draw powers-of-two masks with
/// the finer no coarser than the coarser where they meet. Each level changed (of `levels`, the
/// tiles placed as `neighbourhood` says) becomes the coarsest that obeys and shows no larger
/// error than the level it replaces (`error(k, level)` for the `k`-th tile; level 0 shows
/// none), no finer than `finest(k)`, the finest the tile can draw (what it holds). Returns
/// whether anything changed.
pub fn conform(
    neighbourhood: &Neighbourhood,
    levels: &mut [usize],
    tile_size: usize,
    finest: impl Fn(usize) -> usize,
    error: impl Fn(usize, usize) -> f64,
) -> bool {
    let cells = tile_size - 1;
    let floor_pow2 = |v: usize| 1usize << v.max(1).ilog2();
    // The coarsest power-of-two level of tile `k` at most `bound` (a stride) showing no more
    // error than its level now.
    let settle = |k: usize, level: usize, bound: usize| {
        let now = error(k, level);
        let mut stride = floor_pow2(bound.min(level + 1));
        loop {
            let candidate = stride - 1;
            if candidate <= finest(k) {
                return finest(k);
            }
            if error(k, candidate) <= now {
                return candidate;
            }
            stride /= 2;
        }
    };
    let pairs: Vec<(usize, usize, u8)> = neighbourhood.pyramid_pairs().collect();
    let mut changed = false;
    loop {
        let mut moved = false;
        for &(fine, coarse, d) in &pairs {
            let keep = (cells >> d).max(1);
            let level = settle(coarse, levels[coarse], keep);
            if level != levels[coarse] {
                levels[coarse] = level;
                moved = true;
            }
            let bound = ((levels[coarse] + 1) << d).min(cells);
            let level = settle(fine, levels[fine], bound);
            if level != levels[fine] {
                levels[fine] = level;
                moved = true;
            }
        }
        changed |= moved;
        if !moved {
            return changed;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The neighbourhood of `drawn`'s tiles and their levels.
    fn split(drawn: &[(TileId, usize)]) -> (Neighbourhood, Vec<usize>) {
        let ids: Vec<TileId> = drawn.iter().map(|d| d.0).collect();
        (Neighbourhood::of(&ids), drawn.iter().map(|d| d.1).collect())
    }

    fn levels_around(drawn: &[(TileId, usize)], tile_size: usize) -> Vec<[usize; 4]> {
        let (n, levels) = split(drawn);
        neighbour_levels(&n, &levels, tile_size)
    }

    /// Conforms `drawn` in place; whether anything changed.
    fn conformed(
        drawn: &mut [(TileId, usize)],
        tile_size: usize,
        finest: impl Fn(usize) -> usize,
        error: impl Fn(usize, usize) -> f64,
    ) -> bool {
        let (n, mut levels) = split(drawn);
        let changed = conform(&n, &mut levels, tile_size, finest, error);
        for (d, l) in drawn.iter_mut().zip(levels) {
            d.1 = l;
        }
        changed
    }

    #[test]
    fn neighbours_are_read_north_east_south_west_and_missing_ones_take_the_own_level() {
        let drawn = [
            (TileId::new(1, 1), 3),
            (TileId::new(1, 0), 5),
            (TileId::new(2, 1), 7),
            (TileId::new(0, 0), 2),
        ];
        let n = levels_around(&drawn, 17);
        assert_eq!(n[0], [5, 7, 3, 3]);
        assert_eq!(n[1], [5, 5, 3, 2]);
        assert_eq!(n[2], [7, 7, 7, 3]);
        assert_eq!(n[3], [2, 5, 2, 2]);
    }

    #[test]
    fn a_coarser_neighbour_counts_in_the_finer_tiles_samples() {
        // Level-0 tiles (0, 0) and (1, 0) beside the level-1 tile (1, 0), which covers level-0
        // tiles (2, 0), (3, 0), (2, 1) and (3, 1).
        let drawn = [
            (TileId::new(1, 0), 0),
            (TileId::at(1, 1, 0), 3),
            (TileId::new(0, 0), 1),
        ];
        let n = levels_around(&drawn, 17);
        // East of level-0 tile (1, 0): every 4th sample of the level-1 tile is every 8th of its.
        assert_eq!(n[0][1], 7);
        // The level-1 tile's finer neighbours count as its own level.
        assert_eq!(n[1], [3, 3, 3, 3]);
        // Two levels coarser at its corners-only level: capped at the corners-only level.
        let drawn = [(TileId::new(3, 0), 0), (TileId::at(2, 1, 0), 15)];
        assert_eq!(levels_around(&drawn, 17)[0][1], 15);
    }

    #[test]
    fn conformed_levels_keep_the_finer_tiles_corners_in_powers_of_two() {
        let mut drawn = [
            (TileId::new(1, 0), 4),
            (TileId::at(1, 1, 0), 15),
            (TileId::at(1, 0, 1), 2),
        ];
        let none = |_: usize, level: usize| level as f64;
        assert!(conformed(&mut drawn, 17, |_| 0, none));
        // The level-1 tile keeps every 8th of its samples at most (the level-0 tile's corners
        // are 8 of them apart); the level-0 tile draws a power of two no coarser than that.
        assert_eq!(drawn[1].1, 7);
        assert_eq!(drawn[0].1, 3);
        // Tiles bordering no other level keep their levels.
        assert_eq!(drawn[2].1, 2);
        assert!(!conformed(&mut drawn, 17, |_| 0, none));
        // A tile that cannot draw finer stays at what it holds.
        let mut drawn = [(TileId::new(1, 0), 0), (TileId::at(1, 1, 0), 15)];
        conformed(&mut drawn, 17, |k| if k == 1 { 15 } else { 0 }, none);
        assert_eq!(drawn[1].1, 15);
    }

    #[test]
    fn tiles_meeting_another_pyramid_level_are_on_its_border() {
        let drawn = [
            (TileId::new(1, 0), 0),
            (TileId::at(1, 1, 0), 3),
            (TileId::new(0, 0), 1),
            (TileId::at(1, 1, 1), 2),
        ];
        assert_eq!(
            pyramid_borders(&split(&drawn).0),
            [true, true, false, false]
        );
    }

    #[test]
    fn a_conformed_level_never_shows_more_error_than_the_level_it_replaces() {
        // The level-1 tile's every-8th-sample level errs more than its corners-only level:
        // it goes to every 4th, which errs less.
        let errors = |k: usize, level: usize| match (k, level) {
            (1, 15) => 3.0,
            (1, 7) => 5.0,
            (1, 3) => 2.0,
            _ => 0.0,
        };
        let mut drawn = [(TileId::new(1, 0), 0), (TileId::at(1, 1, 0), 15)];
        conformed(&mut drawn, 17, |_| 0, errors);
        assert_eq!(drawn[1].1, 3);
    }
}
