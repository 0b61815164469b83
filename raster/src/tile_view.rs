//! A framebuffer's tiles as disjoint mutable views, so that threads draw different tiles of the
//! same rows at once.
//!
//! Slices cannot split a row-major buffer into rectangles, so a view keeps a pointer to the
//! buffer and hands out one row of its rectangle at a time. This is the crate's only `unsafe`:
//! the views of one buffer come from one `split` of an exclusive borrow, and their rectangles
//! do not overlap (tested), so no two views ever reach the same element.

use std::marker::PhantomData;

use crate::bin::TileGrid;
use crate::edge::PixelRect;

/// The pixels of one tile of a row-major buffer whose rows start `stride` elements apart.
pub(crate) struct TileView<'a, T> {
    base: *mut T,
    stride: usize,
    rect: PixelRect,
    _buffer: PhantomData<&'a mut [T]>,
}

// SAFETY: a view is an exclusive borrow of its rectangle's elements (see `split`), like a
// `&mut [T]`, which is `Send` when `T` is.
unsafe impl<T: Send> Send for TileView<'_, T> {}

impl<T> TileView<'_, T> {
    /// Columns `x0..x1` of row `y` (screen coordinates, inside the tile).
    #[inline]
    pub fn row(&mut self, y: i64, x0: i64, x1: i64) -> &mut [T] {
        let r = self.rect;
        assert!(
            (r.y0 as i64..r.y1 as i64).contains(&y)
                && r.x0 as i64 <= x0
                && x0 <= x1
                && x1 <= r.x1 as i64,
            "row {y}, columns {x0}..{x1} outside the tile {r:?}"
        );
        let start = y as usize * self.stride + x0 as usize;
        // SAFETY: the asserted range lies inside this view's rectangle, which `split` checked to
        // lie inside the buffer; rectangles of views from one split are disjoint, and `&mut self`
        // lets the caller hold one row of this view at a time, so the slice aliases nothing.
        unsafe { std::slice::from_raw_parts_mut(self.base.add(start), (x1 - x0) as usize) }
    }
}

impl<'a, T> TileView<'a, T> {
    /// The tile's own memory, where its rows lie one after the other in the buffer (a tile as
    /// wide as the buffer's rows are apart), to be drawn in place: no copy out and back.
    /// Otherwise the view itself.
    pub fn lend(self) -> Result<TileBuf<'a, T>, Self> {
        let r = self.rect;
        let width = (r.x1 - r.x0) as usize;
        if r.x0 != 0 || width != self.stride {
            return Err(self);
        }
        let start = r.y0 as usize * self.stride;
        let len = (r.y1 - r.y0) as usize * width;
        // SAFETY: the tile's rows are `stride` elements apart and `stride` wide from column 0,
        // so its elements are exactly `start..start + len`, which `split` checked to lie inside
        // the buffer (its last row ends at `stride * (y1 - 1) + width`); views of one split
        // have disjoint rectangles, and this one is consumed, so the slice, an exclusive borrow
        // for the buffer's `'a`, aliases nothing.
        let pixels = unsafe { std::slice::from_raw_parts_mut(self.base.add(start), len) };
        Ok(TileBuf {
            pixels: Pixels::Lent(pixels),
            rect: r,
            width,
        })
    }
}

impl<T: Copy> TileView<'_, T> {
    /// Copies the tile out of the framebuffer into `pixels` (reusing its allocation).
    pub fn load<'t>(&mut self, mut pixels: Vec<T>) -> TileBuf<'t, T> {
        let r = self.rect;
        pixels.clear();
        // At once: a thread's first tile of a parallel pass comes with an empty allocation.
        pixels.reserve(((r.x1 - r.x0) * (r.y1 - r.y0)) as usize);
        for y in r.y0 as i64..r.y1 as i64 {
            pixels.extend_from_slice(self.row(y, r.x0 as i64, r.x1 as i64));
        }
        TileBuf {
            width: (r.x1 - r.x0) as usize,
            rect: r,
            pixels: Pixels::Owned(pixels),
        }
    }

    /// Copies `tile` (loaded from this view) back into the framebuffer; returns its allocation.
    pub fn store(&mut self, mut tile: TileBuf<'_, T>) -> Vec<T> {
        let r = self.rect;
        assert_eq!(tile.rect, r, "a tile goes back where it came from");
        let width = tile.width;
        for (y, src) in (r.y0 as i64..r.y1 as i64).zip(tile.pixels().chunks_exact(width)) {
            self.row(y, r.x0 as i64, r.x1 as i64).copy_from_slice(src);
        }
        tile.into_allocation()
    }

    /// `load` converting each element to the format the tile is drawn in.
    pub fn load_as<'t, P>(
        &mut self,
        mut pixels: Vec<P>,
        convert: impl Fn(T) -> P,
    ) -> TileBuf<'t, P> {
        let r = self.rect;
        pixels.clear();
        pixels.reserve(((r.x1 - r.x0) * (r.y1 - r.y0)) as usize);
        for y in r.y0 as i64..r.y1 as i64 {
            let row = self.row(y, r.x0 as i64, r.x1 as i64);
            pixels.extend(row.iter().map(|&p| convert(p)));
        }
        TileBuf {
            width: (r.x1 - r.x0) as usize,
            rect: r,
            pixels: Pixels::Owned(pixels),
        }
    }

    /// `store` of a tile loaded by `load_as`, converting each pixel back.
    pub fn store_as<P: Copy>(
        &mut self,
        mut tile: TileBuf<'_, P>,
        convert: impl Fn(P) -> T,
    ) -> Vec<P> {
        let r = self.rect;
        assert_eq!(tile.rect, r, "a tile goes back where it came from");
        let width = tile.width;
        for (y, src) in (r.y0 as i64..r.y1 as i64).zip(tile.pixels().chunks_exact(width)) {
            let row = self.row(y, r.x0 as i64, r.x1 as i64);
            for (d, &s) in row.iter_mut().zip(src) {
                *d = convert(s);
            }
        }
        tile.into_allocation()
    }
}

/// A tile's pixels in contiguous rows, so that a run is a plain slice and a pixel a plain index
/// while the tile is drawn: copied out of the framebuffer (`TileView::load`), or the
/// framebuffer's own memory where the tile's rows lie one after the other there
/// (`TileView::lend`).
pub(crate) struct TileBuf<'a, T> {
    pixels: Pixels<'a, T>,
    rect: PixelRect,
    width: usize,
}

/// Where a tile's pixels are.
enum Pixels<'a, T> {
    Owned(Vec<T>),
    Lent(&'a mut [T]),
}

impl<T> TileBuf<'_, T> {
    /// A tile of `rect` holding `pixels`, row after row, for tests of what draws into tiles.
    #[cfg(test)]
    pub fn new(rect: PixelRect, pixels: Vec<T>) -> Self {
        let width = (rect.x1 - rect.x0) as usize;
        assert_eq!(pixels.len(), width * (rect.y1 - rect.y0) as usize);
        Self {
            pixels: Pixels::Owned(pixels),
            rect,
            width,
        }
    }

    /// The allocation of a copied tile, for the next; none for a lent one.
    fn into_allocation(self) -> Vec<T> {
        match self.pixels {
            Pixels::Owned(v) => v,
            Pixels::Lent(_) => Vec::new(),
        }
    }

    /// The tile's pixels, as `rect` of the screen, `width` to a row.
    #[inline(always)]
    pub fn rect(&self) -> PixelRect {
        self.rect
    }

    /// The tile's pixels, row after row.
    #[inline(always)]
    pub fn pixels(&mut self) -> &mut [T] {
        match &mut self.pixels {
            Pixels::Owned(v) => v,
            Pixels::Lent(s) => s,
        }
    }

    /// Columns `x0..x1` of row `y` (screen coordinates, inside the tile).
    #[inline(always)]
    pub fn row(&mut self, y: i64, x0: i64, x1: i64) -> &mut [T] {
        let r = self.rect;
        let (row, c0, c1) = (y - r.y0 as i64, x0 - r.x0 as i64, x1 - r.x0 as i64);
        // A run past the tile's right edge would reach into the next row: refused.
        assert!(
            (row as u64) < (r.y1 - r.y0) as u64 && 0 <= c0 && c0 <= c1 && c1 <= self.width as i64,
            "row {y}, columns {x0}..{x1} outside the tile {r:?}"
        );
        let start = row as usize * self.width + c0 as usize;
        &mut self.pixels()[start..start + (c1 - c0) as usize]
    }
}

/// Splits `buffer` (the row-major pixels of `grid`'s framebuffer, rows `stride` elements
/// apart) into one view per tile, in tile order. Elements between rows belong to no view.
pub(crate) fn split<'a, T>(
    buffer: &'a mut [T],
    stride: usize,
    grid: &TileGrid,
) -> Vec<TileView<'a, T>> {
    let (width, height) = grid.size();
    assert!(
        width as usize <= stride && buffer.len() >= stride * (height as usize - 1) + width as usize,
        "{width}x{height} pixels, rows {stride} apart, in {} elements",
        buffer.len()
    );
    let base = buffer.as_mut_ptr();
    (0..grid.len())
        .map(|t| TileView {
            base,
            stride,
            rect: grid.rect(t),
            _buffer: PhantomData,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_element_belongs_to_exactly_one_tile_row() {
        let grid = TileGrid::new(150, 70, crate::bin::SMALL_TILE_SIZE);
        let mut buffer = vec![0u32; 150 * 70];
        let mut views = split(&mut buffer, 150, &grid);
        for (t, view) in views.iter_mut().enumerate() {
            let r = grid.rect(t);
            for y in r.y0 as i64..r.y1 as i64 {
                for (x, p) in view.row(y, r.x0 as i64, r.x1 as i64).iter_mut().enumerate() {
                    *p += 1 + (y * 1000 + r.x0 as i64 + x as i64) as u32;
                }
            }
        }
        drop(views);
        for (i, &p) in buffer.iter().enumerate() {
            let (x, y) = (i % 150, i / 150);
            assert_eq!(
                p,
                1 + (y * 1000 + x) as u32,
                "pixel {x},{y} written once, by its tile"
            );
        }
    }

    #[test]
    fn views_of_padded_rows_never_reach_the_padding() {
        let grid = TileGrid::new(150, 70, crate::bin::SMALL_TILE_SIZE);
        let stride = 157;
        let mut buffer = vec![0u32; stride * 69 + 150];
        let mut views = split(&mut buffer, stride, &grid);
        for view in &mut views {
            let mut tile = view.load_as(Vec::new(), |p| p as u64);
            let filled = TileBuf {
                pixels: Pixels::Owned(vec![9u64; tile.pixels().len()]),
                ..tile
            };
            view.store_as(filled, |p| p as u32 + 1);
        }
        drop(views);
        for (i, &p) in buffer.iter().enumerate() {
            assert_eq!(p, if i % stride < 150 { 10 } else { 0 }, "element {i}");
        }
    }

    #[test]
    fn a_loaded_tile_goes_back_unchanged_or_changed_where_drawn() {
        let grid = TileGrid::new(150, 70, crate::bin::SMALL_TILE_SIZE);
        let mut buffer: Vec<u32> = (0..150 * 70).collect();
        let mut views = split(&mut buffer, 150, &grid);
        for (t, view) in views.iter_mut().enumerate() {
            let r = grid.rect(t);
            let mut tile = view.load(Vec::new());
            assert_eq!(
                tile.pixels().len(),
                ((r.x1 - r.x0) * (r.y1 - r.y0)) as usize
            );
            let (y, x) = (r.y1 as i64 - 1, r.x0 as i64 + 1);
            let i = tile.rect().index(y, x);
            assert_eq!(tile.pixels()[i], (y * 150 + x) as u32);
            tile.row(y, x, x + 1)[0] = 1_000_000 + t as u32;
            view.store(tile);
        }
        drop(views);
        for t in 0..grid.len() {
            let r = grid.rect(t);
            let (y, x) = (r.y1 as usize - 1, r.x0 as usize + 1);
            assert_eq!(buffer[y * 150 + x], 1_000_000 + t as u32);
            buffer[y * 150 + x] = (y * 150 + x) as u32;
        }
        assert!(buffer.iter().enumerate().all(|(i, &p)| p == i as u32));
    }

    #[test]
    #[should_panic(expected = "outside the tile")]
    fn a_run_past_a_loaded_tile_is_refused() {
        let grid = TileGrid::new(150, 70, crate::bin::SMALL_TILE_SIZE);
        let mut buffer = vec![0u8; 150 * 70];
        let mut views = split(&mut buffer, 150, &grid);
        views[0].load(Vec::new()).row(0, 60, 65);
    }

    #[test]
    #[should_panic(expected = "outside the tile")]
    fn a_row_outside_the_tile_is_refused() {
        let grid = TileGrid::new(150, 70, crate::bin::SMALL_TILE_SIZE);
        let mut buffer = vec![0u8; 150 * 70];
        let mut views = split(&mut buffer, 150, &grid);
        views[0].row(0, 60, 65);
    }
    #[test]
    fn tiles_as_wide_as_the_rows_are_lent_and_drawn_in_place() {
        // Tiles of 64 over 64x150 elements in rows 64 apart: each tile's rows follow one
        // another, so every tile is lent; at 100 apart (or 150 wide) none is.
        let grid = TileGrid::new(64, 150, crate::bin::SMALL_TILE_SIZE);
        let mut buffer = vec![0u16; 64 * 150];
        for (t, view) in split(&mut buffer, 64, &grid).into_iter().enumerate() {
            let mut tile = view.lend().ok().expect("rows one after another");
            assert_eq!(tile.rect(), grid.rect(t));
            for (i, p) in tile.pixels().iter_mut().enumerate() {
                *p = (t * 10_000 + i) as u16;
            }
        }
        let first_rows = 64 * 64;
        assert_eq!(buffer[..3], [0, 1, 2]);
        assert_eq!(buffer[first_rows..first_rows + 2], [10_000, 10_001]);
        assert_eq!(buffer[64 * 150 - 1], (20_000 + 64 * 22 - 1) as u16);
        let mut padded = vec![0u16; 100 * 150];
        assert!(
            split(&mut padded, 100, &grid)
                .into_iter()
                .all(|v| v.lend().is_err())
        );
        let wide = TileGrid::new(150, 70, crate::bin::SMALL_TILE_SIZE);
        let mut buffer = vec![0u16; 150 * 70];
        assert!(
            split(&mut buffer, 150, &wide)
                .into_iter()
                .all(|v| v.lend().is_err())
        );
    }
}
