//! A tile's pixels: its lists of set-up triangles, run by run of one draw, each run through the
//! span function monomorphised for that draw's state (pixel and depth format, texture filter and
//! texel type, shading, fog). A feature a draw does not use is not in its loop.

use crate::edge::PixelRect;
use crate::pipeline::fixed::{self, AttrPlane, FixedPipeline, FixedTriangle, Span};
use crate::pipeline::float::{self, FloatPipeline, FloatPlane, FloatTriangle};
use crate::pipeline::{Attributes, Pipeline, Setup, TexMode};
use crate::pixel::{Depth16, Depth32, DepthFormat, NoDepth, PixelFormat, Rgb565, Rgba8888};
use crate::sampler::{Bilinear, Filtering, Nearest, NoTexture, TexViews, ViewOf};
use crate::setup::ChunkOut;
use crate::state::RenderState;
use crate::texture::{Filter, TextureFormat};
use crate::tile_view::TileView;

/// One tile of the framebuffer, as views of its colour and depth.
pub(crate) struct TileTarget<'a> {
    pub rect: PixelRect,
    pub color: ColorTile<'a>,
    pub depth: DepthTile<'a>,
}

/// A tile's colour in the framebuffer's format.
pub(crate) enum ColorTile<'a> {
    Rgb565(TileView<'a, u16>),
    Rgba8888(TileView<'a, [u8; 4]>),
}

/// A tile's depth in the framebuffer's format, if it has one.
pub(crate) enum DepthTile<'a> {
    None,
    D16(TileView<'a, u16>),
    D32(TileView<'a, u32>),
}

/// What the pixels of one draw need.
pub(crate) struct DrawShade<'a, 't> {
    pub state: &'a RenderState<'t>,
    pub attrs: &'a Attributes<'t>,
    pub views: &'a TexViews<'t>,
}

/// A pipeline's pixel stage.
pub(crate) trait Shade: Pipeline {
    /// Draws the triangles `list` (indices into `tris`, all of draw `draw`, with their planes
    /// in `planes`) into `tile`. Returns the fragments that passed the depth test.
    fn run(
        draw: &DrawShade,
        tris: &[Self::Triangle],
        planes: &[Self::Plane],
        list: &[u32],
        tile: &mut TileTarget,
    ) -> u64;
}

/// Draws tile `t` from the chunks' lists, in submission order. Returns the fragments written.
pub(crate) fn raster_tile<P: Shade>(
    t: usize,
    chunks: &[ChunkOut<P>],
    draws: &[DrawShade],
    tile: &mut TileTarget,
) -> u64 {
    let mut fragments = 0;
    for chunk in chunks {
        let list = chunk.bins.list(t);
        let mut k = 0;
        while k < list.len() {
            let d = chunk.tris[list[k] as usize].draw();
            let mut e = k + 1;
            while e < list.len() && chunk.tris[list[e] as usize].draw() == d {
                e += 1;
            }
            fragments += P::run(
                &draws[d as usize],
                &chunk.tris,
                &chunk.planes,
                &list[k..e],
                tile,
            );
            k = e;
        }
    }
    fragments
}

/// Calls `$f::<P, D>($color, $depth, ...)` with the tile's colour and depth formats; `D` is
/// `NoDepth` (and the depth view `None`) when the draw does not test depth.
macro_rules! with_formats {
    ($tile:expr, $depth_on:expr, $f:ident, $($arg:expr),*) => {{
        let TileTarget { rect, color, depth } = $tile;
        match color {
            ColorTile::Rgb565(c) => with_formats!(@depth Rgb565, c, depth, *rect, $depth_on, $f, $($arg),*),
            ColorTile::Rgba8888(c) => with_formats!(@depth Rgba8888, c, depth, *rect, $depth_on, $f, $($arg),*),
        }
    }};
    (@depth $p:ty, $c:expr, $d:expr, $rect:expr, $depth_on:expr, $f:ident, $($arg:expr),*) => {
        match $d {
            DepthTile::D16(d) if $depth_on => $f::<$p, Depth16>($rect, $c, Some(d), $($arg),*),
            DepthTile::D32(d) if $depth_on => $f::<$p, Depth32>($rect, $c, Some(d), $($arg),*),
            _ => $f::<$p, NoDepth>($rect, $c, None, $($arg),*),
        }
    };
}

/// Walks the spans of `list` inside `rect` and hands each, cut to the tile, to `row`.
#[inline(always)]
fn spans<P: PixelFormat, D: DepthFormat, T: Setup>(
    rect: PixelRect,
    color: &mut TileView<'_, P::Pixel>,
    mut depth: Option<&mut TileView<'_, D::Value>>,
    tris: &[T],
    list: &[u32],
    mut row: impl FnMut(&T, Span<'_, P, D>) -> u64,
) -> u64 {
    let mut fragments = 0;
    let (tx0, tx1) = (rect.x0 as i64, rect.x1 as i64);
    for &i in list {
        let t = &tris[i as usize];
        t.coverage()
            .for_each_span(rect.y0 as i64, rect.y1 as i64, |y, x0, x1| {
                let (xs, xe) = (x0.max(tx0), x1.min(tx1));
                if xs >= xe {
                    return;
                }
                let span = Span {
                    y,
                    x0,
                    x1,
                    xs,
                    color: color.row(y, xs, xe),
                    depth: match &mut depth {
                        Some(d) => d.row(y, xs, xe),
                        None => &mut [],
                    },
                };
                fragments += row(t, span);
            });
    }
    fragments
}

impl Shade for FixedPipeline {
    fn run(
        draw: &DrawShade,
        tris: &[FixedTriangle],
        planes: &[AttrPlane],
        list: &[u32],
        tile: &mut TileTarget,
    ) -> u64 {
        with_formats!(
            tile,
            draw.attrs.depth,
            fixed_texture,
            draw,
            (tris, planes),
            list
        )
    }
}

/// Chooses the texture filter and texel type.
fn fixed_texture<'r, 'v, P: PixelFormat, D: DepthFormat>(
    rect: PixelRect,
    color: &'r mut TileView<'v, P::Pixel>,
    depth: Option<&'r mut TileView<'v, D::Value>>,
    draw: &'r DrawShade,
    tris: (&'r [FixedTriangle], &'r [AttrPlane]),
    list: &'r [u32],
) -> u64 {
    let binding = draw
        .state
        .texture
        .filter(|_| draw.attrs.tex != TexMode::Off);
    let args = (rect, color, depth, draw, tris, list);
    let Some(binding) = binding else {
        return fixed_flags::<P, D, NoTexture>(args);
    };
    match (binding.sampler.filter, binding.texture.format()) {
        (Filter::Nearest, TextureFormat::Rgb565) => fixed_flags::<P, D, Nearest<u16>>(args),
        (Filter::Nearest, TextureFormat::Rgba8888) => fixed_flags::<P, D, Nearest<[u8; 4]>>(args),
        (Filter::Bilinear, TextureFormat::Rgb565) => fixed_flags::<P, D, Bilinear<u16>>(args),
        (Filter::Bilinear, TextureFormat::Rgba8888) => fixed_flags::<P, D, Bilinear<[u8; 4]>>(args),
    }
}

/// The arguments of a fixed run, passed down the dispatch as one.
type FixedArgs<'r, 'v, 'c, 'x, P, D> = (
    PixelRect,
    &'r mut TileView<'v, <P as PixelFormat>::Pixel>,
    Option<&'r mut TileView<'v, <D as DepthFormat>::Value>>,
    &'r DrawShade<'c, 'x>,
    (&'r [FixedTriangle], &'r [AttrPlane]),
    &'r [u32],
);

/// Chooses the shading and fog specialisation and runs the spans.
fn fixed_flags<P: PixelFormat, D: DepthFormat, F: Filtering>(
    args: FixedArgs<'_, '_, '_, '_, P, D>,
) -> u64 {
    fn run<P: PixelFormat, D: DepthFormat, F: Filtering, const SHADE: bool, const FOG: bool>(
        (rect, color, depth, draw, (tris, planes), list): FixedArgs<'_, '_, '_, '_, P, D>,
    ) -> u64 {
        let views = F::Texel::select(draw.views);
        let attrs = draw.attrs;
        spans::<P, D, _>(rect, color, depth, tris, list, |t, span| {
            fixed::shade_row::<P, D, F, SHADE, FOG>(t, planes, span, views.get(t.level()), attrs)
        })
    }
    match (args.3.attrs.shade, args.3.attrs.fog) {
        (false, false) => run::<P, D, F, false, false>(args),
        (true, false) => run::<P, D, F, true, false>(args),
        (false, true) => run::<P, D, F, false, true>(args),
        (true, true) => run::<P, D, F, true, true>(args),
    }
}

impl Shade for FloatPipeline {
    fn run(
        draw: &DrawShade,
        tris: &[FloatTriangle],
        _planes: &[FloatPlane],
        list: &[u32],
        tile: &mut TileTarget,
    ) -> u64 {
        with_formats!(tile, draw.attrs.depth, float_spans, draw, tris, list)
    }
}

fn float_spans<P: PixelFormat, D: DepthFormat>(
    rect: PixelRect,
    color: &mut TileView<'_, P::Pixel>,
    depth: Option<&mut TileView<'_, D::Value>>,
    draw: &DrawShade,
    tris: &[FloatTriangle],
    list: &[u32],
) -> u64 {
    let texture = draw
        .state
        .texture
        .filter(|_| draw.attrs.tex != TexMode::Off);
    spans::<P, D, _>(rect, color, depth, tris, list, |t, span| {
        let tex = texture.map(|b| (&b.texture.levels()[t.level()], b.sampler));
        float::shade_row::<P, D>(t, span, tex, draw.attrs)
    })
}
