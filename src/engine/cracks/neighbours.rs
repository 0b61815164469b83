//! What a tile knows of its neighbours at frame time: the levels they are drawn at.

use std::collections::HashMap;

use super::Side;
use crate::db::grid::TileId;

/// For each drawn tile `(id, level)`, the levels of its four neighbours in [`Side::ALL`] order.
/// A neighbour not drawn this frame counts as the tile's own level.
pub fn neighbour_levels(drawn: &[(TileId, usize)]) -> Vec<[usize; 4]> {
    let levels: HashMap<TileId, usize> = drawn.iter().copied().collect();
    drawn
        .iter()
        .map(|&(id, level)| {
            Side::ALL.map(|side| {
                let (dx, dy) = match side {
                    Side::North => (0, -1),
                    Side::East => (1, 0),
                    Side::South => (0, 1),
                    Side::West => (-1, 0),
                };
                let x = id.x.checked_add_signed(dx);
                let y = id.y.checked_add_signed(dy);
                x.zip(y)
                    .and_then(|(x, y)| levels.get(&TileId::new(x, y)).copied())
                    .unwrap_or(level)
            })
        })
        .collect()
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
        let n = neighbour_levels(&drawn);
        assert_eq!(n[0], [5, 7, 3, 3]);
        assert_eq!(n[1], [5, 5, 3, 2]);
        assert_eq!(n[2], [7, 7, 7, 3]);
        assert_eq!(n[3], [2, 5, 2, 2]);
    }
}
