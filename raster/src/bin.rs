//! Binning: the screen is cut into tiles, and every set-up triangle is listed in each tile its
//! pixel rectangle touches, in submission order. A tile is then drawn by one thread from its own
//! lists, with its colour and depth in cache, and no tile waits for another.
//!
//! Set-up runs in chunks on several threads; each chunk bins its own triangles, so binning needs
//! no lock and no merge: a tile reads chunk after chunk, which is submission order.

use crate::edge::PixelRect;

/// Tile side in pixels: fewer triangles straddle two tiles and are walked twice than at 64,
/// fewer tiles are loaded and stored, and the tile (64 to 128 KiB) still sits in a level-2
/// cache, where one of 256 does not (`examples/tile_size.rs`, measured in docs/raster.md).
pub(crate) const TILE_SIZE: u32 = 128;

/// Tile side in pixels when tiles of `TILE_SIZE` would leave threads too few to share out
/// (llvmpipe's 64: a 64x64 tile of RGBA8888 colour and 32-bit depth is 32 KiB, an L1 cache's
/// worth).
pub(crate) const SMALL_TILE_SIZE: u32 = 64;

/// Tiles a thread should have to draw in a pass: the last tiles of a pass leave the other
/// threads waiting, so with fewer, larger tiles the wait grows.
const TILES_PER_THREAD: u32 = 8;

/// The most colour and depth a frame drawn on one thread may hold to be drawn as one tile,
/// which is drawn in place (`TileView::lend`): a 320x240 frame takes less time so than in
/// tiles of 128 in RGB565 with a 16-bit depth (300 KiB) and in RGBA8888 with a 32-bit depth
/// (600 KiB) alike (`examples/tile_size.rs`, measured in docs/raster.md).
const ONE_TILE_BYTES: u64 = 1 << 20;

/// The tile side a flush drawn on `threads` threads into a `width x height` framebuffer of
/// `bytes` of colour and depth a pixel uses: one tile covering the frame where one thread draws
/// a frame of at most `ONE_TILE_BYTES` (no triangle then straddles two tiles and is walked
/// twice, and the frame is not copied), else `TILE_SIZE`, or `SMALL_TILE_SIZE`
/// where that leaves fewer than `TILES_PER_THREAD` tiles a thread (at 1280x720, 60 tiles of
/// 128 serve two threads; eight take tiles of 64).
pub(crate) fn tile_size(threads: usize, width: u32, height: u32, bytes: u32) -> u32 {
    if threads <= 1 && width as u64 * height as u64 * bytes as u64 <= ONE_TILE_BYTES {
        return width.max(height).next_power_of_two().max(TILE_SIZE);
    }
    let tiles = width.div_ceil(TILE_SIZE) as usize * height.div_ceil(TILE_SIZE) as usize;
    if threads > 1 && tiles < (TILES_PER_THREAD as usize).saturating_mul(threads) {
        SMALL_TILE_SIZE
    } else {
        TILE_SIZE
    }
}

/// The tiles of a framebuffer: `cols x rows` square tiles of `1 << shift` pixels (`tile_size`
/// for the flush's threads and size, or the caller's `Rasterizer::with_tile_size`), the last
/// column and row cut at the framebuffer's edge.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct TileGrid {
    width: u32,
    height: u32,
    cols: u32,
    rows: u32,
    shift: u32,
}

impl TileGrid {
    /// The tiles of side `size` (a power of two) of a `width x height` framebuffer.
    pub fn new(width: u32, height: u32, size: u32) -> Self {
        assert!(size.is_power_of_two());
        Self {
            width,
            height,
            cols: width.div_ceil(size),
            rows: height.div_ceil(size),
            shift: size.trailing_zeros(),
        }
    }

    /// Number of tiles.
    pub fn len(&self) -> usize {
        (self.cols * self.rows) as usize
    }

    /// The pixels of tile `t` (row-major tile order).
    pub fn rect(&self, t: usize) -> PixelRect {
        let (tx, ty) = (t as u32 % self.cols, t as u32 / self.cols);
        let size = 1u64 << self.shift;
        let edge = |i: u32, end: u32| (i as u64 * size).min(end as u64) as i32;
        PixelRect {
            x0: edge(tx, self.width),
            y0: edge(ty, self.height),
            x1: edge(tx + 1, self.width),
            y1: edge(ty + 1, self.height),
        }
    }

    /// The framebuffer's size.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }
}

/// One set-up chunk's bins: for every tile, the indices (into the chunk's triangles) of the
/// triangles whose rectangle touches it, in order.
#[derive(Debug, Default)]
pub(crate) struct Bins {
    lists: Vec<Vec<u32>>,
}

impl Bins {
    /// Empties every list and sizes the bins for `grid` (keeping their allocations).
    pub fn reset(&mut self, grid: &TileGrid) {
        self.lists.resize_with(grid.len(), Vec::new);
        self.lists.truncate(grid.len());
        for l in &mut self.lists {
            l.clear();
        }
    }

    /// Lists triangle `index` in every tile that `rect` (non-empty, on screen) touches.
    #[inline]
    pub fn insert(&mut self, grid: &TileGrid, rect: PixelRect, index: u32) {
        debug_assert!(rect.x0 >= 0 && rect.y0 >= 0 && rect.x0 < rect.x1 && rect.y0 < rect.y1);
        let shift = grid.shift;
        let (tx0, tx1) = (rect.x0 as u32 >> shift, (rect.x1 as u32 - 1) >> shift);
        let (ty0, ty1) = (rect.y0 as u32 >> shift, (rect.y1 as u32 - 1) >> shift);
        for ty in ty0..=ty1 {
            for tx in tx0..=tx1 {
                self.lists[(ty * grid.cols + tx) as usize].push(index);
            }
        }
    }

    /// The triangles listed in tile `t`.
    #[inline]
    pub fn list(&self, t: usize) -> &[u32] {
        &self.lists[t]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_cover_the_framebuffer_once_with_cut_edges() {
        let grid = TileGrid::new(150, 70, SMALL_TILE_SIZE);
        assert_eq!((grid.cols, grid.rows, grid.len()), (3, 2, 6));
        let mut hits = vec![0u8; 150 * 70];
        for t in 0..grid.len() {
            let r = grid.rect(t);
            for y in r.y0..r.y1 {
                for x in r.x0..r.x1 {
                    hits[(y * 150 + x) as usize] += 1;
                }
            }
        }
        assert!(hits.iter().all(|&h| h == 1));
        assert_eq!(
            grid.rect(5),
            PixelRect {
                x0: 128,
                y0: 64,
                x1: 150,
                y1: 70
            }
        );
    }

    #[test]
    fn threads_get_small_tiles_only_when_large_ones_are_too_few_to_share() {
        // RGBA8888 with a 32-bit depth: 8 bytes a pixel.
        assert_eq!(tile_size(1, 640, 480, 8), TILE_SIZE);
        assert_eq!(tile_size(1, 8192, 8192, 4), TILE_SIZE);
        // 1280x720 is 10 x 6 tiles of 128: enough for two threads, not for eight.
        assert_eq!(tile_size(2, 1280, 720, 4), TILE_SIZE);
        assert_eq!(tile_size(8, 1280, 720, 4), SMALL_TILE_SIZE);
        assert_eq!(tile_size(2, 320, 240, 4), SMALL_TILE_SIZE);
        assert_eq!(tile_size(usize::MAX, 1, 1, 4), SMALL_TILE_SIZE);
        // A thread count beyond u32 (on a 64-bit target) is not cut to its low bits, where
        // 2^32 would read as 0.
        if let Ok(threads) = usize::try_from(1u64 << 32) {
            assert_eq!(tile_size(threads, 8192, 8192, 4), SMALL_TILE_SIZE);
        }
    }

    #[test]
    fn one_thread_draws_a_frame_that_fits_the_cache_as_one_tile() {
        // The handheld's 320x240 is one tile in RGB565 with a 16-bit depth (4 bytes a pixel)
        // and in RGBA8888 with a 32-bit depth (8), and so is a 480x272 LCD's frame.
        assert_eq!(tile_size(1, 320, 240, 4), 512);
        assert_eq!(tile_size(1, 240, 320, 8), 512);
        assert_eq!(tile_size(1, 480, 272, 8), 512);
        assert_eq!(tile_size(1, 100, 60, 8), TILE_SIZE);
        assert_eq!(tile_size(1, 8192, 32, 4), 8192);
        // Past the budget: tiles of 128.
        assert_eq!(tile_size(1, 800, 480, 4), TILE_SIZE);
        assert_eq!(tile_size(1, 8192, 33, 4), TILE_SIZE);
        let grid = TileGrid::new(320, 240, tile_size(1, 320, 240, 4));
        assert_eq!(grid.len(), 1);
        assert_eq!(
            grid.rect(0),
            PixelRect {
                x0: 0,
                y0: 0,
                x1: 320,
                y1: 240
            }
        );
    }

    #[test]
    fn a_triangle_is_listed_in_every_tile_its_rectangle_touches_in_order() {
        let grid = TileGrid::new(200, 200, SMALL_TILE_SIZE);
        let mut bins = Bins::default();
        bins.reset(&grid);
        let rect = |x0, y0, x1, y1| PixelRect { x0, y0, x1, y1 };
        bins.insert(&grid, rect(60, 10, 70, 20), 0);
        bins.insert(&grid, rect(0, 0, 64, 64), 1);
        bins.insert(&grid, rect(63, 63, 65, 65), 2);
        assert_eq!(bins.list(0), &[0, 1, 2]);
        assert_eq!(bins.list(1), &[0, 2]);
        assert_eq!(bins.list(4), &[2]);
        assert_eq!(bins.list(5), &[2]);
        assert!(bins.list(2).is_empty());
        bins.reset(&grid);
        assert!((0..grid.len()).all(|t| bins.list(t).is_empty()));
    }
}
