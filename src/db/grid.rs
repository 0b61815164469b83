//! Grid ids: which tile of an archive's grid a piece of data belongs to, shared by the database,
//! the pagers and the renderer.

use std::fmt;

/// A tile of the grid: `x` counts east, `y` south. Ordered row-major.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct TileId {
    /// Column, from the west.
    pub x: u32,
    /// Row, from the north.
    pub y: u32,
}

impl TileId {
    /// The tile in column `x`, row `y`.
    pub const fn new(x: u32, y: u32) -> Self {
        TileId { x, y }
    }
}

impl Ord for TileId {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        (self.y, self.x).cmp(&(other.y, other.x))
    }
}

impl PartialOrd for TileId {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl fmt::Display for TileId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "tile ({}, {})", self.x, self.y)
    }
}
