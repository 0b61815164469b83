//! The tile grid: which tile of an archive a piece of data belongs to, and the belts around a
//! tile (the rings the pagers fill), shared by the database, the pagers and the renderer.

use std::fmt;

use crate::error::{Error, Result};

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

/// The grid of `tiles_x x tiles_y` tiles, and its belts: the rings of tiles at one Chebyshev
/// distance around a tile.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Grid {
    tiles_x: u32,
    tiles_y: u32,
}

impl Grid {
    /// A grid of `tiles_x` columns and `tiles_y` rows; both must be at least 1.
    pub fn new(tiles_x: u32, tiles_y: u32) -> Result<Self> {
        if tiles_x == 0 || tiles_y == 0 {
            return Err(Error::setting(
                "tile grid",
                format!("{tiles_x} x {tiles_y}"),
                "at least one tile each way",
            ));
        }
        Ok(Grid { tiles_x, tiles_y })
    }

    /// Columns.
    pub fn tiles_x(&self) -> u32 {
        self.tiles_x
    }

    /// Rows.
    pub fn tiles_y(&self) -> u32 {
        self.tiles_y
    }

    /// Whether `id` lies on the grid.
    pub fn contains(&self, id: TileId) -> bool {
        id.x < self.tiles_x && id.y < self.tiles_y
    }

    /// The belt of `id` around `center`: their Chebyshev distance.
    pub fn ring(center: TileId, id: TileId) -> u32 {
        center.x.abs_diff(id.x).max(center.y.abs_diff(id.y))
    }

    /// The farthest non-empty belt around `center`.
    pub fn max_ring(&self, center: TileId) -> u32 {
        let dx = center
            .x
            .max(self.tiles_x - 1 - center.x.min(self.tiles_x - 1));
        let dy = center
            .y
            .max(self.tiles_y - 1 - center.y.min(self.tiles_y - 1));
        dx.max(dy)
    }

    /// The tiles of belt `d` around `center`, clipped to the grid, nearest first (squared
    /// Euclidean distance in tiles), ties in row-major order.
    pub fn belt(&self, center: TileId, d: u32) -> Vec<TileId> {
        let (cx, cy) = (i64::from(center.x), i64::from(center.y));
        let d = i64::from(d);
        let (x0, x1) = ((cx - d).max(0), (cx + d).min(i64::from(self.tiles_x) - 1));
        let (y0, y1) = ((cy - d).max(0), (cy + d).min(i64::from(self.tiles_y) - 1));
        let mut tiles = Vec::new();
        for y in y0..=y1 {
            let edge_row = (y - cy).abs() == d;
            for x in x0..=x1 {
                if edge_row || (x - cx).abs() == d {
                    tiles.push(TileId::new(x as u32, y as u32));
                }
            }
        }
        tiles.sort_by_key(|t| (distance2(center, *t), *t));
        tiles
    }

    /// The tile under a viewpoint given in tile units (tile `(x, y)` covers `[x, x + 1) x
    /// [y, y + 1)`). Off the grid: the nearest tile when `nearest_when_off`, else `None`; a
    /// non-finite position is off the grid and has no nearest tile.
    pub fn locate(&self, position: (f64, f64), nearest_when_off: bool) -> Option<TileId> {
        let (px, py) = position;
        if !px.is_finite() || !py.is_finite() {
            return None;
        }
        let (fx, fy) = (px.floor(), py.floor());
        let inside = |f: f64, n: u32| f >= 0.0 && f < f64::from(n);
        let on_grid = inside(fx, self.tiles_x) && inside(fy, self.tiles_y);
        if !on_grid && !nearest_when_off {
            return None;
        }
        let clamp = |f: f64, n: u32| f.clamp(0.0, f64::from(n - 1)) as u32;
        Some(TileId::new(
            clamp(fx, self.tiles_x),
            clamp(fy, self.tiles_y),
        ))
    }
}

/// Squared Euclidean distance between two tiles, in tiles.
pub fn distance2(a: TileId, b: TileId) -> u64 {
    let (dx, dy) = (u64::from(a.x.abs_diff(b.x)), u64::from(a.y.abs_diff(b.y)));
    dx * dx + dy * dy
}
