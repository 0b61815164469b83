//! Which samples a strip-mask level keeps.
//!
//! For a tile of `s = 2^n + 1` samples per side, mask level `l` (`l = 0 ..= s - 2`) keeps the
//! samples whose column `i` and row `j` are both kept, where an index is kept when it is a
//! multiple of `l + 1` or is the last index `s - 1`. Level 0 is the full tile.

/// Whether mask level `level` of a tile with `tile_size` samples per side keeps grid index `index`
/// (a column or a row); a sample `(i, j)` is kept when both its indices are.
pub fn keeps_index(tile_size: usize, level: usize, index: usize) -> bool {
    index.is_multiple_of(level + 1) || index + 1 == tile_size
}

/// The grid indices (columns or rows) that mask level `level` keeps, in increasing order.
pub fn kept_indices(tile_size: usize, level: usize) -> Vec<usize> {
    (0..tile_size)
        .filter(|&i| keeps_index(tile_size, level, i))
        .collect()
}

/// The number of mask levels of a tile with `tile_size` samples per side (`tile_size - 1`).
pub fn level_count(tile_size: usize) -> usize {
    tile_size.saturating_sub(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn level_zero_keeps_everything_and_last_level_keeps_corners() {
        assert_eq!(kept_indices(5, 0), vec![0, 1, 2, 3, 4]);
        assert_eq!(kept_indices(5, 1), vec![0, 2, 4]);
        assert_eq!(kept_indices(5, 2), vec![0, 3, 4]);
        assert_eq!(kept_indices(5, 3), vec![0, 4]);
        assert_eq!(level_count(129), 128);
    }
}
