//! A surface's tiles lent to the threads: each tile's colour and depth drawn where they are when
//! its rows lie one after the other in the surface's memory, else copied into a buffer the
//! thread reuses, converted to the format the inner loops draw, and back.

use crate::fragments::Fragments;
use crate::layout::{rgba_to_xbgr, rgba_to_xrgb, swap_565, xbgr_to_rgba, xrgb_to_rgba};
use crate::shade::{ColorTile, DepthTile};
use crate::tile_view::{TileBuf, TileView};

/// The allocations of the tiles a thread has drawn, for the next tile it loads: the colour's
/// and the depth's apart, so that an RGB565 tile with a 16-bit depth reuses both, and the
/// fragment buffer.
#[derive(Default)]
pub(super) struct TileBuffers {
    u16s: Vec<u16>,
    rgba: Vec<[u8; 4]>,
    depth16s: Vec<u16>,
    u32s: Vec<u32>,
    fragments: Option<Box<Fragments>>,
}

impl TileBuffers {
    /// The fragment buffer of the thread's last tile, readied for another, or a new one for
    /// its first.
    pub(super) fn fragments(&mut self) -> Box<Fragments> {
        match self.fragments.take() {
            Some(mut f) => {
                f.for_another_tile();
                f
            }
            None => Box::new(Fragments::new()),
        }
    }

    /// Keeps a tile's fragment buffer, empty once its draws are finished, for the next tile.
    pub(super) fn keep_fragments(&mut self, fragments: Box<Fragments>) {
        debug_assert_eq!(fragments.held(), 0);
        self.fragments = Some(fragments);
    }
}

/// The tile of `view` drawn in place where the view lends it (`TileView::lend`), else copied
/// into `spare`'s allocation, with the view to store the copy back through.
fn lend_or_load<'a, T: Copy>(
    view: TileView<'a, T>,
    spare: &mut Vec<T>,
) -> (TileBuf<'a, T>, Option<TileView<'a, T>>) {
    match view.lend() {
        Ok(tile) => (tile, None),
        Err(mut view) => (view.load(std::mem::take(spare)), Some(view)),
    }
}

/// A tile of the colour memory in the surface's layout. A tile is drawn as RGB565 words or
/// RGBA bytes; the other layouts are converted on the way in and out (see `crate::layout`).
pub(super) enum ColorView<'a> {
    Rgb565(TileView<'a, u16>),
    Bgr565(TileView<'a, u16>),
    Xrgb8888(TileView<'a, u32>),
    Xbgr8888(TileView<'a, u32>),
    Rgba8888(TileView<'a, [u8; 4]>),
}

impl<'a> ColorView<'a> {
    /// The tile to draw: the framebuffer's own memory where the view lends it (`TileView::lend`;
    /// RGB565 and RGBA8888 are drawn as they are stored), else a copy in `spare`'s allocation,
    /// converted, with the view to store it back through (`store`).
    pub(super) fn load(self, spare: &mut TileBuffers) -> (ColorTile<'a>, Option<Self>) {
        use std::mem::take;
        match self {
            ColorView::Rgb565(v) => {
                let (t, v) = lend_or_load(v, &mut spare.u16s);
                (ColorTile::Rgb565(t), v.map(ColorView::Rgb565))
            }
            ColorView::Bgr565(mut v) => {
                let t = v.load_as(take(&mut spare.u16s), swap_565);
                (ColorTile::Rgb565(t), Some(ColorView::Bgr565(v)))
            }
            ColorView::Xrgb8888(mut v) => {
                let t = v.load_as(take(&mut spare.rgba), xrgb_to_rgba);
                (ColorTile::Rgba8888(t), Some(ColorView::Xrgb8888(v)))
            }
            ColorView::Xbgr8888(mut v) => {
                let t = v.load_as(take(&mut spare.rgba), xbgr_to_rgba);
                (ColorTile::Rgba8888(t), Some(ColorView::Xbgr8888(v)))
            }
            ColorView::Rgba8888(v) => {
                let (t, v) = lend_or_load(v, &mut spare.rgba);
                (ColorTile::Rgba8888(t), v.map(ColorView::Rgba8888))
            }
        }
    }

    /// Copies a tile `load` copied back into the framebuffer, converted, keeping its
    /// allocation in `spare`.
    pub(super) fn store(&mut self, tile: ColorTile, spare: &mut TileBuffers) {
        match (self, tile) {
            (ColorView::Rgb565(v), ColorTile::Rgb565(t)) => spare.u16s = v.store(t),
            (ColorView::Bgr565(v), ColorTile::Rgb565(t)) => spare.u16s = v.store_as(t, swap_565),
            (ColorView::Xrgb8888(v), ColorTile::Rgba8888(t)) => {
                spare.rgba = v.store_as(t, rgba_to_xrgb)
            }
            (ColorView::Xbgr8888(v), ColorTile::Rgba8888(t)) => {
                spare.rgba = v.store_as(t, rgba_to_xbgr)
            }
            (ColorView::Rgba8888(v), ColorTile::Rgba8888(t)) => spare.rgba = v.store(t),
            _ => unreachable!("a tile goes back to its own buffer"),
        }
    }
}

/// A tile of the depth buffer in the framebuffer's format, if it has one.
pub(super) enum DepthView<'a> {
    None,
    D16(TileView<'a, u16>),
    D32(TileView<'a, u32>),
}

impl<'a> DepthView<'a> {
    /// As `ColorView::load`: the depth buffer's own memory where the view lends it, else a copy.
    pub(super) fn load(self, spare: &mut TileBuffers) -> (DepthTile<'a>, Option<Self>) {
        match self {
            DepthView::None => (DepthTile::None, None),
            DepthView::D16(v) => {
                let (t, v) = lend_or_load(v, &mut spare.depth16s);
                (DepthTile::D16(t), v.map(DepthView::D16))
            }
            DepthView::D32(v) => {
                let (t, v) = lend_or_load(v, &mut spare.u32s);
                (DepthTile::D32(t), v.map(DepthView::D32))
            }
        }
    }

    /// As `ColorView::store`.
    pub(super) fn store(&mut self, tile: DepthTile, spare: &mut TileBuffers) {
        match (self, tile) {
            (DepthView::None, DepthTile::None) => {}
            (DepthView::D16(v), DepthTile::D16(t)) => spare.depth16s = v.store(t),
            (DepthView::D32(v), DepthTile::D32(t)) => spare.u32s = v.store(t),
            _ => unreachable!("a tile goes back to its own buffer"),
        }
    }
}
