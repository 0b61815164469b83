//! What a tile knows of its neighbours at frame time: the levels they are drawn at, counted in
//! its own samples — a neighbour may be a tile of another level of the pyramid — and, for
//! stitching, the levels that make the borders between pyramid levels meet.

use std::collections::HashMap;

use super::Side;
use crate::db::grid::TileId;

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

/// The drawn tiles by id, and the coarsest pyramid level among them.
struct Drawn {
    index: HashMap<TileId, usize>,
    coarsest: u8,
}

impl Drawn {
    fn new(drawn: &[(TileId, usize)]) -> Self {
        Drawn {
            index: drawn
                .iter()
                .enumerate()
                .map(|(k, &(id, _))| (id, k))
                .collect(),
            coarsest: drawn.iter().map(|(id, _)| id.level).max().unwrap_or(0),
        }
    }

    /// The drawn tile across `side` of `id` of its level or a coarser one: its index in the
    /// list, and how many levels coarser it is. `None` when the tiles there are finer, or none
    /// is drawn.
    fn across(&self, id: TileId, side: Side) -> Option<(usize, u8)> {
        let next = across(id, side)?;
        (id.level..=self.coarsest).find_map(|level| {
            let k = *self.index.get(&next.ancestor(level))?;
            Some((k, level - id.level))
        })
    }
}

/// For each drawn tile `(id, level)` (tiles of `tile_size` samples), the levels of its four
/// neighbours in [`Side::ALL`] order, counted in its own samples: a neighbour of its pyramid
/// level counts with its level; one `d` levels coarser, whose samples are `2^d` of this tile's
/// apart, with the level whose kept samples are its kept samples, `(l + 1) 2^d - 1` (at most
/// the corners-only level); finer neighbours — which match their borders to this tile — and a
/// side where nothing is drawn count as the tile's own level.
pub fn neighbour_levels(drawn: &[(TileId, usize)], tile_size: usize) -> Vec<[usize; 4]> {
    let index = Drawn::new(drawn);
    let last = tile_size.saturating_sub(2);
    drawn
        .iter()
        .map(|&(id, level)| {
            Side::ALL.map(|side| match index.across(id, side) {
                Some((k, 0)) => drawn[k].1,
                Some((k, coarser)) => (((drawn[k].1 + 1) << coarser) - 1).min(last),
                None => level,
            })
        })
        .collect()
}

/// For each drawn tile, whether it meets a drawn tile of another level of the pyramid across
/// one of its sides (the tiles [`conform`] may change).
pub fn pyramid_borders(drawn: &[(TileId, usize)]) -> Vec<bool> {
    let index = Drawn::new(drawn);
    let mut border = vec![false; drawn.len()];
    for (a, &(id, _)) in drawn.iter().enumerate() {
        for side in Side::ALL {
            if let Some((b, _)) = index.across(id, side).filter(|&(_, c)| c > 0) {
                border[a] = true;
                border[b] = true;
            }
        }
    }
    border
}

/// Makes stitching close the borders between pyramid levels: a tile bordering a finer one
/// keeps that tile's corners (its samples there are `2^d` of the finer tile's apart, so its
/// mask keeps no more than every `(s - 1) / 2^d`-th), and both draw powers-of-two masks with
/// the finer no coarser than the coarser where they meet. Each level changed becomes the
/// coarsest that obeys and shows no larger error than the level it replaces (`error(k, level)`
/// for the `k`-th tile; level 0 shows none), no finer than `finest(k)`, the finest the tile can
/// draw (what it holds). Returns whether anything changed.
pub fn conform(
    drawn: &mut [(TileId, usize)],
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
    let mut changed = false;
    loop {
        let mut moved = false;
        let pairs: Vec<(usize, usize, u8)> = {
            let index = Drawn::new(drawn);
            drawn
                .iter()
                .enumerate()
                .flat_map(|(a, &(id, _))| {
                    let index = &index;
                    Side::ALL
                        .into_iter()
                        .filter_map(move |side| index.across(id, side))
                        .filter(|&(_, coarser)| coarser > 0)
                        .map(move |(b, coarser)| (a, b, coarser))
                })
                .collect()
        };
        for (fine, coarse, d) in pairs {
            let keep = (cells >> d).max(1);
            let level = settle(coarse, drawn[coarse].1, keep);
            if level != drawn[coarse].1 {
                drawn[coarse].1 = level;
                moved = true;
            }
            let bound = ((drawn[coarse].1 + 1) << d).min(cells);
            let level = settle(fine, drawn[fine].1, bound);
            if level != drawn[fine].1 {
                drawn[fine].1 = level;
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

    #[test]
    fn neighbours_are_read_north_east_south_west_and_missing_ones_take_the_own_level() {
        let drawn = [
            (TileId::new(1, 1), 3),
            (TileId::new(1, 0), 5),
            (TileId::new(2, 1), 7),
            (TileId::new(0, 0), 2),
        ];
        let n = neighbour_levels(&drawn, 17);
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
        let n = neighbour_levels(&drawn, 17);
        // East of level-0 tile (1, 0): every 4th sample of the level-1 tile is every 8th of its.
        assert_eq!(n[0][1], 7);
        // The level-1 tile's finer neighbours count as its own level.
        assert_eq!(n[1], [3, 3, 3, 3]);
        // Two levels coarser at its corners-only level: capped at the corners-only level.
        let drawn = [(TileId::new(3, 0), 0), (TileId::at(2, 1, 0), 15)];
        assert_eq!(neighbour_levels(&drawn, 17)[0][1], 15);
    }

    #[test]
    fn conformed_levels_keep_the_finer_tiles_corners_in_powers_of_two() {
        let mut drawn = [
            (TileId::new(1, 0), 4),
            (TileId::at(1, 1, 0), 15),
            (TileId::at(1, 0, 1), 2),
        ];
        let none = |_: usize, level: usize| level as f64;
        assert!(conform(&mut drawn, 17, |_| 0, none));
        // The level-1 tile keeps every 8th of its samples at most (the level-0 tile's corners
        // are 8 of them apart); the level-0 tile draws a power of two no coarser than that.
        assert_eq!(drawn[1].1, 7);
        assert_eq!(drawn[0].1, 3);
        // Tiles bordering no other level keep their levels.
        assert_eq!(drawn[2].1, 2);
        assert!(!conform(&mut drawn, 17, |_| 0, none));
        // A tile that cannot draw finer stays at what it holds.
        let mut drawn = [(TileId::new(1, 0), 0), (TileId::at(1, 1, 0), 15)];
        conform(&mut drawn, 17, |k| if k == 1 { 15 } else { 0 }, none);
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
        assert_eq!(pyramid_borders(&drawn), [true, true, false, false]);
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
        conform(&mut drawn, 17, |_| 0, errors);
        assert_eq!(drawn[1].1, 3);
    }
}
