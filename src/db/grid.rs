//! The tile grid and its pyramid: which tile (or overview node) of an archive a piece of data
//! belongs to, and the belts around a tile (the rings the pagers fill), shared by the database,
//! the pagers and the renderer.
//!
//! Level 0 is the model's own grid of tiles. A tile of pyramid level `k + 1` covers the 2 x 2
//! tiles of level `k` below it with the same number of samples at twice the spacing, up to one
//! root tile; a level's grid is its finer level's halved, rounded up.

use std::collections::{HashMap, HashSet};
use std::fmt;
use std::hash::BuildHasherDefault;

use rustc_hash::FxHasher;

use crate::error::{Error, Result};

/// A map keyed by tile. FxHash rather than the standard SipHash, whose rounds of 64-bit
/// arithmetic a 32-bit core composes from many instructions, and the engine looks tiles up
/// every frame; tile ids are grid positions, not keys a party could choose to collide.
pub type TileMap<V> = HashMap<TileId, V, BuildHasherDefault<FxHasher>>;

/// A set of tiles, hashed as `TileMap`.
pub type TileSet = HashSet<TileId, BuildHasherDefault<FxHasher>>;

/// A tile of the pyramid: `level` 0 is the model's own grid, each level above covers 2 x 2 tiles
/// of the one below; `x` counts east, `y` south, in tiles of its level. Ordered by level, then
/// row-major.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct TileId {
    /// Pyramid level: 0 for the model's own tiles.
    pub level: u8,
    /// Column, from the west.
    pub x: u32,
    /// Row, from the north.
    pub y: u32,
}

impl TileId {
    /// The level-0 tile in column `x`, row `y`.
    pub const fn new(x: u32, y: u32) -> Self {
        TileId { level: 0, x, y }
    }

    /// The tile in column `x`, row `y` of pyramid level `level`.
    pub const fn at(level: u8, x: u32, y: u32) -> Self {
        TileId { level, x, y }
    }

    /// The tile of the level above that covers this one.
    pub fn parent(self) -> TileId {
        TileId::at(self.level + 1, self.x / 2, self.y / 2)
    }

    /// The tile of level `level` (at or above this one's) that covers this one.
    pub fn ancestor(self, level: u8) -> TileId {
        debug_assert!(level >= self.level);
        let up = u32::from(level - self.level);
        TileId::at(level, self.x >> up, self.y >> up)
    }

    /// The four tiles of the level below that this one covers, north-west, north-east,
    /// south-west, south-east (some may lie beyond that level's grid). Panics at level 0.
    pub fn children(self) -> [TileId; 4] {
        assert!(self.level > 0, "a level-0 tile has no children");
        let (x, y, l) = (2 * self.x, 2 * self.y, self.level - 1);
        [
            TileId::at(l, x, y),
            TileId::at(l, x + 1, y),
            TileId::at(l, x, y + 1),
            TileId::at(l, x + 1, y + 1),
        ]
    }

    /// Level-0 tiles along one side of this tile: `2^level`.
    pub fn span(self) -> u32 {
        1 << self.level
    }
}

impl Ord for TileId {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        (self.level, self.y, self.x).cmp(&(other.level, other.y, other.x))
    }
}

impl PartialOrd for TileId {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl fmt::Display for TileId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.level {
            0 => write!(f, "tile ({}, {})", self.x, self.y),
            k => write!(f, "tile ({}, {}) of level {k}", self.x, self.y),
        }
    }
}

/// The pyramid over a grid of level-0 tiles: every level's grid, from level 0 up to the root
/// (one tile).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Pyramid {
    /// `grids[k]` is level `k`'s grid; the last one is 1 x 1.
    grids: Vec<Grid>,
}

impl Pyramid {
    /// The pyramid over `tiles_x x tiles_y` level-0 tiles.
    pub fn new(tiles_x: u32, tiles_y: u32) -> Result<Self> {
        let mut grids = vec![Grid::new(tiles_x, tiles_y)?];
        while let Some(&g) = grids.last().filter(|g| g.tiles_x > 1 || g.tiles_y > 1) {
            grids.push(Grid::at_level(
                g.level + 1,
                g.tiles_x.div_ceil(2),
                g.tiles_y.div_ceil(2),
            )?);
        }
        Ok(Pyramid { grids })
    }

    /// The number of levels, the root's included: `1 + ceil(log2(max(tiles_x, tiles_y)))`.
    pub fn levels(&self) -> usize {
        self.grids.len()
    }

    /// Level `level`'s grid. Panics beyond the root.
    pub fn grid(&self, level: u8) -> Grid {
        self.grids[usize::from(level)]
    }

    /// The root: the one tile of the coarsest level.
    pub fn root(&self) -> TileId {
        TileId::at((self.grids.len() - 1) as u8, 0, 0)
    }

    /// Whether `id` is a tile of the pyramid.
    pub fn contains(&self, id: TileId) -> bool {
        self.grids
            .get(usize::from(id.level))
            .is_some_and(|g| g.contains(id))
    }

    /// The tiles of the level below that `id` covers and that exist (1 to 4 of them).
    pub fn children(&self, id: TileId) -> impl Iterator<Item = TileId> + '_ {
        id.children().into_iter().filter(|&c| self.contains(c))
    }

    /// Tiles in the whole pyramid.
    pub fn tile_count(&self) -> u64 {
        self.grids.iter().map(|g| g.tile_count()).sum()
    }

    /// Every tile of the pyramid, level 0 first, each level row-major.
    pub fn tiles(&self) -> impl Iterator<Item = TileId> + '_ {
        self.grids.iter().flat_map(|g| {
            (0..g.tiles_y).flat_map(move |y| (0..g.tiles_x).map(move |x| TileId::at(g.level, x, y)))
        })
    }
}

/// The grid of `tiles_x x tiles_y` tiles, and its belts: the rings of tiles at one Chebyshev
/// distance around a tile.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Grid {
    level: u8,
    tiles_x: u32,
    tiles_y: u32,
}

impl Grid {
    /// A grid of `tiles_x` columns and `tiles_y` rows; both must be at least 1.
    pub fn new(tiles_x: u32, tiles_y: u32) -> Result<Self> {
        Grid::at_level(0, tiles_x, tiles_y)
    }

    /// The grid of pyramid level `level`, `tiles_x` columns and `tiles_y` rows.
    pub fn at_level(level: u8, tiles_x: u32, tiles_y: u32) -> Result<Self> {
        if tiles_x == 0 || tiles_y == 0 {
            return Err(Error::setting(
                "tile grid",
                format!("{tiles_x} x {tiles_y}"),
                "at least one tile each way",
            ));
        }
        Ok(Grid {
            level,
            tiles_x,
            tiles_y,
        })
    }

    /// The pyramid level whose tiles this grid holds.
    pub fn level(&self) -> u8 {
        self.level
    }

    /// Columns.
    pub fn tiles_x(&self) -> u32 {
        self.tiles_x
    }

    /// Rows.
    pub fn tiles_y(&self) -> u32 {
        self.tiles_y
    }

    /// Whether `id` is a tile of this grid (its level, its column and row on it).
    pub fn contains(&self, id: TileId) -> bool {
        id.level == self.level && id.x < self.tiles_x && id.y < self.tiles_y
    }

    /// Tiles in the grid.
    pub fn tile_count(&self) -> u64 {
        u64::from(self.tiles_x) * u64::from(self.tiles_y)
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
        let level = center.level;
        let (cx, cy) = (i64::from(center.x), i64::from(center.y));
        let d = i64::from(d);
        let (x0, x1) = ((cx - d).max(0), (cx + d).min(i64::from(self.tiles_x) - 1));
        let (y0, y1) = ((cy - d).max(0), (cy + d).min(i64::from(self.tiles_y) - 1));
        let mut tiles = Vec::new();
        for y in y0..=y1 {
            let edge_row = (y - cy).abs() == d;
            for x in x0..=x1 {
                if edge_row || (x - cx).abs() == d {
                    tiles.push(TileId::at(level, x as u32, y as u32));
                }
            }
        }
        tiles.sort_by_key(|t| (distance2(center, *t), *t));
        tiles
    }

    /// The tile under a viewpoint given in units of this grid's tiles (tile `(x, y)` covers
    /// `[x, x + 1) x [y, y + 1)`). Off the grid: the nearest tile when `nearest_when_off`, else `None`; a
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
        Some(TileId::at(
            self.level,
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
