//! The tiles of a pass handed to the threads: each tile drawn by one thread, its triangles in
//! submission order.

use rayon::prelude::*;

use super::loans::{ColorView, DepthView, TileBuffers};
use crate::bin::TileGrid;
use crate::setup::ChunkOut;
use crate::shade::{DrawShade, Shade, TileTarget, raster_tile};
use crate::surface::{ColorMut, DepthMut, Surface};
use crate::tile_view::{TileView, split};

/// Draws every tile that has triangles, in parallel, each thread reusing its tile buffers.
/// Returns the fragments written.
pub(super) fn raster_tiles<P: Shade>(
    fb: &mut Surface,
    chunks: &[ChunkOut<P>],
    draws: &[DrawShade],
    grid: &TileGrid,
    threads: usize,
) -> u64 {
    fn views<'a, T, V>(
        pixels: &'a mut [T],
        stride: usize,
        grid: &TileGrid,
        view: impl Fn(TileView<'a, T>) -> V,
    ) -> Vec<V> {
        split(pixels, stride, grid).into_iter().map(view).collect()
    }
    let colors: Vec<ColorView> = match &mut fb.color {
        ColorMut::Rgb565(c) => views(c.pixels, c.stride, grid, ColorView::Rgb565),
        ColorMut::Bgr565(c) => views(c.pixels, c.stride, grid, ColorView::Bgr565),
        ColorMut::Xrgb8888(c) => views(c.pixels, c.stride, grid, ColorView::Xrgb8888),
        ColorMut::Xbgr8888(c) => views(c.pixels, c.stride, grid, ColorView::Xbgr8888),
        ColorMut::Rgba8888(c) => views(c.pixels, c.stride, grid, ColorView::Rgba8888),
    };
    let width = grid.size().0 as usize;
    let depths: Vec<DepthView> = match &mut fb.depth {
        DepthMut::None => (0..grid.len()).map(|_| DepthView::None).collect(),
        DepthMut::D16(d) => views(d, width, grid, DepthView::D16),
        DepthMut::D32(d) => views(d, width, grid, DepthView::D32),
    };
    let tiles = colors
        .into_iter()
        .zip(depths)
        .enumerate()
        .filter(|(t, _)| chunks.iter().any(|c| !c.bins.list(*t).is_empty()));
    let draw = |spare: &mut TileBuffers, (t, (color, depth)): (usize, (ColorView, DepthView))| {
        let (color, mut color_view) = color.load(spare);
        let (depth, mut depth_view) = depth.load(spare);
        let mut target = TileTarget {
            rect: grid.rect(t),
            color,
            depth,
            fragments: spare.fragments(),
        };
        let fragments = raster_tile::<P>(t, chunks, draws, &mut target);
        if let Some(view) = &mut color_view {
            view.store(target.color, spare);
        }
        if let Some(view) = &mut depth_view {
            view.store(target.depth, spare);
        }
        spare.keep_fragments(target.fragments);
        fragments
    };
    if threads > 1 {
        let tiles: Vec<_> = tiles.collect();
        tiles
            .into_par_iter()
            .map_init(TileBuffers::default, draw)
            .sum()
    } else {
        let mut spare = TileBuffers::default();
        tiles.map(|tile| draw(&mut spare, tile)).sum()
    }
}
