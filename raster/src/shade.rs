//! A tile's pixels: its lists of set-up triangles, run by run of one draw, each run through the
//! span function monomorphised for that draw's state (pixel and depth format, texture filter and
//! texel type, shading, fog). A feature a draw does not use is not in its loop.

use crate::edge::PixelRect;
use crate::fragments::Fragments;
use crate::isa::{Cpu, v3_twin};
use crate::pipeline::fixed::{
    self, AttrPlane, FixedPipeline, FixedTriangle, NarrowPlanes, RunPiece, Span,
};
use crate::pipeline::float::{self, FloatPipeline};
use crate::pipeline::{Attributes, Pipeline, Setup, TexMode};
use crate::pixel::{Depth16, Depth32, DepthStorage, NoDepth, PixelFormat, Rgb565, Rgba8888};
use crate::sampler::{Bilinear, Filtering, Nearest, NoTexture, TexViews, ViewOf};
use crate::setup::ChunkOut;
use crate::small::small_triangle;
use crate::state::RenderState;
use crate::texture::{Filter, TextureFormat};
use crate::tile_view::TileBuf;

/// One tile of the framebuffer, its colour and depth copied out while it is drawn.
pub(crate) struct TileTarget<'a> {
    pub rect: PixelRect,
    pub color: ColorTile<'a>,
    pub depth: DepthTile<'a>,
    /// The fixed pipeline's fragment buffer, which the thread lends from tile to tile: a new
    /// one would zero its arrays, kilobytes, for every draw in every tile.
    pub fragments: Box<Fragments>,
}

/// A tile's colour in the framebuffer's format.
pub(crate) enum ColorTile<'a> {
    Rgb565(TileBuf<'a, u16>),
    Rgba8888(TileBuf<'a, [u8; 4]>),
}

/// A tile's depth in the framebuffer's format, if it has one.
pub(crate) enum DepthTile<'a> {
    None,
    D16(TileBuf<'a, u16>),
    D32(TileBuf<'a, u32>),
}

/// What the pixels of one draw need.
pub(crate) struct DrawShade<'a, 't> {
    pub state: &'a RenderState<'t>,
    pub attrs: &'a Attributes<'t>,
    pub views: &'a TexViews<'t>,
    /// The loops the rasterizer runs (`crate::isa`).
    pub cpu: Cpu,
}

/// Part of a tile's triangles from one set-up chunk: `list` indexes `tris`, whose planes are in
/// `planes`.
pub(crate) struct Piece<'a, P: Pipeline> {
    pub tris: &'a [P::Triangle],
    pub planes: &'a [P::Plane],
    pub list: &'a [u32],
}

/// A stretch of tile `tile`'s triangles in the chunks' lists, from position `from` to `to`
/// (each a chunk and an index in its list for the tile): the triangles of one draw.
pub(crate) struct Stretch<'a, P: Pipeline> {
    chunks: &'a [ChunkOut<P>],
    tile: usize,
    from: (usize, usize),
    to: (usize, usize),
}

impl<'a, P: Pipeline> Stretch<'a, P> {
    /// The stretch's part of each chunk it spans, in order.
    pub fn pieces(&self) -> impl Iterator<Item = Piece<'a, P>> + '_ {
        (self.from.0..=self.to.0).map(|c| {
            let chunk = &self.chunks[c];
            let list = chunk.bins.list(self.tile);
            let start = if c == self.from.0 { self.from.1 } else { 0 };
            let end = if c == self.to.0 {
                self.to.1
            } else {
                list.len()
            };
            Piece {
                tris: &chunk.tris,
                planes: &chunk.planes,
                list: &list[start..end],
            }
        })
    }
}

/// A pipeline's pixel stage.
pub(crate) trait Shade: Pipeline + Sized {
    /// Draws the triangles of `stretch` (all of draw `draw`), in order, into `tile`. Returns the
    /// fragments that passed the depth test.
    fn run(draw: &DrawShade, stretch: &Stretch<Self>, tile: &mut TileTarget<'_>) -> u64;
}

/// Draws tile `t` from the chunks' lists, in submission order. Returns the fragments written.
///
/// The triangles of one draw go to the pixel stage in one call whatever the chunks they were
/// set up in: on several threads a pass is set up in many chunks, and a call per chunk would run
/// a colour stage on a part-filled fragment buffer at the end of each
/// (docs/optimisation-notes.md).
pub(crate) fn raster_tile<P: Shade>(
    t: usize,
    chunks: &[ChunkOut<P>],
    draws: &[DrawShade],
    tile: &mut TileTarget<'_>,
) -> u64 {
    let mut fragments = 0;
    let mut run = |draw: u32, from, to| {
        let stretch = Stretch {
            chunks,
            tile: t,
            from,
            to,
        };
        fragments += P::run(&draws[draw as usize], &stretch, tile);
    };
    // The draw of the stretch being gathered, where it starts, and where it has reached.
    let mut current: Option<(u32, (usize, usize))> = None;
    let mut end = (0, 0);
    for (c, chunk) in chunks.iter().enumerate() {
        let list = chunk.bins.list(t);
        let mut k = 0;
        while k < list.len() {
            let d = chunk.tris[list[k] as usize].draw();
            let mut e = k + 1;
            while e < list.len() && chunk.tris[list[e] as usize].draw() == d {
                e += 1;
            }
            match current {
                Some((draw, _)) if draw == d => {}
                _ => {
                    if let Some((draw, from)) = current {
                        run(draw, from, end);
                    }
                    current = Some((d, (c, k)));
                }
            }
            end = (c, e);
            k = e;
        }
    }
    if let Some((draw, from)) = current {
        run(draw, from, end);
    }
    fragments
}

/// Calls `$f::<P, D>($color, $depth, ...)` with the tile's colour and depth formats; `D` is
/// `NoDepth` (and the depth view `None`) when the draw does not test depth.
macro_rules! with_formats {
    ($tile:expr, $depth_on:expr, $f:ident, $($arg:expr),*) => {{
        let TileTarget { rect, color, depth, .. } = $tile;
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

/// Walks the spans of `stretch`'s triangles inside `rect` and hands each, cut to the tile, to
/// `row` with the planes of the triangle's chunk.
#[inline(always)]
fn spans<P: PixelFormat, D: DepthStorage, S: Shade>(
    rect: PixelRect,
    color: &mut TileBuf<'_, P::Pixel>,
    mut depth: Option<&mut TileBuf<'_, D::Value>>,
    stretch: &Stretch<S>,
    mut row: impl FnMut(&S::Triangle, &[S::Plane], Span<'_, P, D>) -> u64,
) -> u64 {
    let mut fragments = 0;
    let (tx0, tx1) = (rect.x0 as i64, rect.x1 as i64);
    for piece in stretch.pieces() {
        for &i in piece.list {
            let t = &piece.tris[i as usize];
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
                    fragments += row(t, piece.planes, span);
                });
        }
    }
    fragments
}

impl Shade for FixedPipeline {
    fn run(draw: &DrawShade, stretch: &Stretch<FixedPipeline>, tile: &mut TileTarget<'_>) -> u64 {
        let frags = &mut *tile.fragments;
        with_formats!(tile, draw.attrs.depth, fixed_texture, draw, stretch, frags)
    }
}

/// Chooses the texture filter and texel type.
fn fixed_texture<'r, 'b, P: PixelFormat, D: DepthStorage>(
    rect: PixelRect,
    color: &'r mut TileBuf<'b, P::Pixel>,
    depth: Option<&'r mut TileBuf<'b, D::Value>>,
    draw: &'r DrawShade,
    stretch: &'r Stretch<'r, FixedPipeline>,
    frags: &'r mut Fragments,
) -> u64 {
    let binding = draw
        .state
        .texture
        .filter(|_| draw.attrs.tex != TexMode::Off);
    let args = (rect, color, depth, draw, stretch, frags);
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
type FixedArgs<'r, 'b, 'v, 'c, 'x, P, D> = (
    PixelRect,
    &'r mut TileBuf<'b, <P as PixelFormat>::Pixel>,
    Option<&'r mut TileBuf<'b, <D as DepthStorage>::Value>>,
    &'r DrawShade<'c, 'x>,
    &'r Stretch<'r, FixedPipeline>,
    &'r mut Fragments,
);

/// Chooses the shading and fog specialisation and runs the spans.
fn fixed_flags<P: PixelFormat, D: DepthStorage, F: Filtering>(
    args: FixedArgs<'_, '_, '_, '_, '_, P, D>,
) -> u64 {
    fn run<P: PixelFormat, D: DepthStorage, F: Filtering, const SHADE: bool, const FOG: bool>(
        (rect, color, mut depth, draw, stretch, frags): FixedArgs<'_, '_, '_, '_, '_, P, D>,
    ) -> u64 {
        let views = F::Texel::select(draw.views);
        let attrs = draw.attrs;
        #[cfg(test)]
        if fixed::reference::enabled() {
            return spans::<P, D, _>(rect, color, depth, stretch, |t, planes, span| {
                fixed::reference::shade_row::<P, D, F, SHADE, FOG>(
                    t,
                    planes,
                    span,
                    views.get(t.level()),
                    attrs,
                )
            });
        }
        let written = frags.written();
        let tile = color.rect();
        let mut flush =
            |frags: &mut Fragments| frags.finish::<P, F, SHADE, FOG>(color, views, attrs, draw.cpu);
        for p in stretch.pieces() {
            triangles::<D, F, SHADE, FOG>(
                (
                    rect,
                    tile,
                    depth.as_deref_mut(),
                    attrs,
                    p.tris,
                    p.planes,
                    p.list,
                ),
                frags,
                &mut flush,
                draw.cpu,
            );
        }
        frags.finish::<P, F, SHADE, FOG>(color, views, attrs, draw.cpu);
        frags.written() - written
    }
    match (args.3.attrs.shade, args.3.attrs.fog) {
        (false, false) => run::<P, D, F, false, false>(args),
        (true, false) => run::<P, D, F, true, false>(args),
        (false, true) => run::<P, D, F, false, true>(args),
        (true, true) => run::<P, D, F, true, true>(args),
    }
}

/// What the triangles of a tile need besides the fragment buffer and its colour stage.
type TrianglesArgs<'r, 'b, 't, D> = (
    PixelRect,
    PixelRect,
    Option<&'r mut TileBuf<'b, <D as DepthStorage>::Value>>,
    &'r Attributes<'t>,
    &'r [FixedTriangle],
    &'r [AttrPlane],
    &'r [u32],
);

/// The triangles `list` inside `rect` of the tile `tile`, in order, into `frags`; `flush` is
/// the colour stage, the only part that depends on the colour format. Behind that call, these
/// loops are built once for both colour formats (compile time and code size: `cargo llvm-lines
/// -p stripmask-raster`); the call runs once per full buffer. Runs the x86-64-v3 twin where
/// `cpu` allows (what each costs: docs/raster.md, *Where the time goes*).
#[inline(never)]
fn triangles<D: DepthStorage, F: Filtering, const SHADE: bool, const FOG: bool>(
    args: TrianglesArgs<'_, '_, '_, D>,
    frags: &mut Fragments,
    flush: &mut dyn FnMut(&mut Fragments),
    cpu: Cpu,
) {
    if cpu.v3() {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `cpu.v3()` holds only where the CPU has every feature the twin is built for.
        return unsafe { triangles_v3::<D, F, SHADE, FOG>(args, frags, flush) };
    }
    triangles_in::<D, F, SHADE, FOG>(args, frags, flush)
}

v3_twin! {
    /// `triangles` built for x86-64-v3 (see `crate::isa`).
    fn triangles_v3<D: DepthStorage, F: Filtering, const SHADE: bool, const FOG: bool>(
        args: TrianglesArgs<'_, '_, '_, D>,
        frags: &mut Fragments,
        flush: &mut dyn FnMut(&mut Fragments),
    ) {
        triangles_in::<D, F, SHADE, FOG>(args, frags, flush)
    }
}

/// The triangle loop of `triangles`, built into each of its twins.
#[inline(always)]
fn triangles_in<D: DepthStorage, F: Filtering, const SHADE: bool, const FOG: bool>(
    (rect, tile, mut depth, attrs, tris, planes, list): TrianglesArgs<'_, '_, '_, D>,
    frags: &mut Fragments,
    flush: &mut dyn FnMut(&mut Fragments),
) {
    let test = fixed::DepthTest::new(attrs);
    for &i in list {
        let t = &tris[i as usize];
        let grey = SHADE && t.grey;
        if !frags.accepts(t.level(), grey) {
            flush(frags);
        }
        frags.hold(t.level(), grey);
        let args = (rect, tile, depth.as_deref_mut(), planes, test);
        match (t.narrow, grey) {
            (false, false) => triangle::<D, F, SHADE, false, FOG, false>(t, frags, flush, args),
            (false, true) => triangle::<D, F, true, true, FOG, false>(t, frags, flush, args),
            (true, true) => triangle::<D, F, true, true, FOG, true>(t, frags, flush, args),
            (true, false) => triangle::<D, F, SHADE, false, FOG, true>(t, frags, flush, args),
        }
    }
}

/// What the rows of one triangle need besides the triangle and the fragment buffer.
type TriangleArgs<'r, 'b, D> = (
    PixelRect,
    PixelRect,
    Option<&'r mut TileBuf<'b, <D as DepthStorage>::Value>>,
    &'r [AttrPlane],
    fixed::DepthTest,
);

/// The rows of triangle `t` inside the tile `rect`: the row step for each run (cut to the tile,
/// in pieces that fit the buffer), the colour stage (`flush`) whenever the buffer is full.
#[inline(always)]
fn triangle<
    D: DepthStorage,
    F: Filtering,
    const SHADE: bool,
    const GREY: bool,
    const FOG: bool,
    const NARROW: bool,
>(
    t: &FixedTriangle,
    frags: &mut Fragments,
    flush: &mut dyn FnMut(&mut Fragments),
    (rect, tile, depth, planes, test): TriangleArgs<'_, '_, D>,
) {
    if NARROW && t.coverage.is_small() {
        let p = NarrowPlanes::new::<D, F, SHADE, GREY, FOG>(t, planes);
        if p.per_pixel() {
            return small_triangle::<D, F, SHADE, GREY, FOG>(
                &p, t, tile, depth, frags, flush, test,
            );
        }
    }
    spans_of::<D, F, SHADE, GREY, FOG, NARROW>(t, frags, flush, (rect, tile), depth, planes, test);
}

/// The general row step of `triangle`: its spans inside `rect` of the tile `tile`, in pieces
/// that fit the buffer.
///
/// Not inlined: out of the triangle loop, which is then a small triangle's set-up and row loop
/// and little else, and runs in fewer instructions (docs/optimisation-notes.md).
#[inline(never)]
fn spans_of<
    D: DepthStorage,
    F: Filtering,
    const SHADE: bool,
    const GREY: bool,
    const FOG: bool,
    const NARROW: bool,
>(
    t: &FixedTriangle,
    frags: &mut Fragments,
    flush: &mut dyn FnMut(&mut Fragments),
    (rect, tile): (PixelRect, PixelRect),
    mut depth: Option<&mut TileBuf<'_, D::Value>>,
    planes: &[AttrPlane],
    test: fixed::DepthTest,
) {
    let (tx0, tx1) = (rect.x0 as i64, rect.x1 as i64);
    t.coverage
        .for_each_span(rect.y0 as i64, rect.y1 as i64, |y, x0, x1| {
            let (mut xs, xe) = (x0.max(tx0), x1.min(tx1));
            while xs < xe {
                if frags.room() == 0 {
                    flush(frags);
                }
                let e = xe.min(xs + frags.room() as i64);
                // The tile's buffers hold its pixels row after row, as the small rows index
                // them.
                let at = tile.index(y, xs);
                let depth = match &mut depth {
                    Some(d) => &mut d.pixels()[at..at + (e - xs) as usize],
                    None => &mut [],
                };
                let piece = RunPiece {
                    y,
                    x0,
                    x1,
                    xs,
                    xe: e,
                    at,
                };
                fixed::run_fragments::<D, F, SHADE, GREY, FOG, NARROW>(
                    t, planes, piece, depth, frags, test,
                );
                xs = e;
            }
        });
}

impl Shade for FloatPipeline {
    fn run(draw: &DrawShade, stretch: &Stretch<FloatPipeline>, tile: &mut TileTarget<'_>) -> u64 {
        with_formats!(tile, draw.attrs.depth, float_spans, draw, stretch)
    }
}

fn float_spans<P: PixelFormat, D: DepthStorage>(
    rect: PixelRect,
    color: &mut TileBuf<'_, P::Pixel>,
    depth: Option<&mut TileBuf<'_, D::Value>>,
    draw: &DrawShade,
    stretch: &Stretch<FloatPipeline>,
) -> u64 {
    let texture = draw
        .state
        .texture
        .filter(|_| draw.attrs.tex != TexMode::Off);
    spans::<P, D, _>(rect, color, depth, stretch, |t, _, span| {
        let tex = texture.map(|b| (&b.texture.levels()[t.level()], b.sampler));
        float::shade_row::<P, D>(t, span, tex, draw.attrs)
    })
}

#[cfg(test)]
mod tests {
    use glam::{DMat4, DVec3};
    use proptest::prelude::*;

    use crate::pipeline::fixed::reference;
    use crate::{
        ColorFormat, Compare, CullMode, DepthFormat, DepthMode, DrawStats, Filter, Fog,
        Framebuffer, Indices, Mesh, MipFilter, Perspective, Rasterizer, RenderState, Sampler,
        Shading, Texture, TextureBinding, Topology, Transform, Vertex, Wrap,
    };

    /// One random case: triangles in a small view, and the state to draw them with.
    #[derive(Clone, Debug)]
    struct Case {
        vertices: Vec<Vertex>,
        color: ColorFormat,
        depth: DepthFormat,
        compare: u8,
        write: bool,
        gouraud: bool,
        texture: u8,
        filter: bool,
        mips: bool,
        repeat: bool,
        perspective: u8,
        fog: bool,
        tile: u32,
    }

    fn case() -> impl Strategy<Value = Case> {
        // A triangle: a centre, a size (most a few pixels across, some the whole view), and
        // three corners around it, each with texture coordinates and a colour.
        let corner = (
            -1.0f64..1.0,
            -1.0f64..1.0,
            -1.0f64..1.0,
            (-3.0f32..5.0, -3.0f32..5.0),
            any::<[u8; 3]>(),
        );
        let triangle = (
            (-800i32..800, -600i32..600, -1400i32..600),
            prop_oneof![4 => 20.0f64..400.0, 1 => 400.0f64..3000.0],
            proptest::collection::vec(corner, 3),
        );
        (
            proptest::collection::vec(triangle, 1..40),
            (0u8..2, 0u8..3, 0u8..3, any::<bool>()),
            (any::<bool>(), any::<bool>(), 0u8..3, any::<bool>()),
            (any::<bool>(), any::<bool>(), 0u8..4, any::<bool>()),
            prop_oneof![Just(8u32), Just(16), Just(64), Just(128)],
        )
            .prop_map(
                |(
                    tris,
                    (color, depth, compare, write),
                    (gouraud, grey, texture, filter),
                    (mips, repeat, perspective, fog),
                    tile,
                )| {
                    let mut vertices = vec![];
                    for (k, ((cx, cy, cz), size, corners)) in tris.into_iter().enumerate() {
                        for (dx, dy, dz, uv, c) in corners {
                            let c = if grey { [c[0]; 3] } else { c };
                            // Some triangles far beyond the texture-coordinate limit.
                            let s = if k % 9 == 8 { 300.0 } else { 1.0 };
                            let p = [
                                cx as f64 + dx * size,
                                cy as f64 + dy * size,
                                cz as f64 + dz * size,
                            ];
                            vertices.push(Vertex::new(p.map(|v| v as i32), [uv.0 * s, uv.1], c));
                        }
                    }
                    Case {
                        vertices,
                        color: [ColorFormat::Rgb565, ColorFormat::Rgba8888][color as usize],
                        depth: [DepthFormat::None, DepthFormat::D16, DepthFormat::D32]
                            [depth as usize],
                        compare,
                        write,
                        gouraud,
                        texture,
                        filter,
                        mips,
                        repeat,
                        perspective,
                        fog,
                        tile,
                    }
                },
            )
    }

    fn textures() -> [Texture; 2] {
        let rgba: Vec<[u8; 4]> = (0..16 * 8)
            .map(|k| {
                [
                    (k * 37 % 256) as u8,
                    (k * 11 % 256) as u8,
                    (k * 5) as u8,
                    255,
                ]
            })
            .collect();
        let t8888 = Texture::from_rgba8(16, 8, rgba).unwrap();
        let t565 =
            Texture::from_rgb565(8, 16, (0..8 * 16).map(|k| (k * 2654) as u16).collect()).unwrap();
        [t565, t8888]
    }

    /// Draws the case's triangles (as a list, in three draws) and returns the buffers' bytes
    /// and the statistics.
    fn draw(c: &Case, textures: &[Texture; 2]) -> (Vec<u8>, Vec<u8>, DrawStats) {
        let mut fb = Framebuffer::new(75, 53, c.color, c.depth).unwrap();
        fb.clear([12, 34, 56]);
        let texture = (c.texture > 0).then(|| {
            let t = &textures[c.texture as usize - 1];
            if c.mips {
                t.clone().with_mipmaps()
            } else {
                t.clone()
            }
        });
        let state = RenderState {
            cull: CullMode::None,
            depth: DepthMode {
                compare: [Compare::Less, Compare::LessEqual, Compare::Always][c.compare as usize],
                write: c.write,
            },
            shading: if c.gouraud {
                Shading::Gouraud
            } else {
                Shading::Flat([200, 150, 100])
            },
            texture: texture.as_ref().map(|t| {
                TextureBinding::new(
                    t,
                    Sampler {
                        filter: if c.filter {
                            Filter::Bilinear
                        } else {
                            Filter::Nearest
                        },
                        mip: if c.mips {
                            MipFilter::Nearest
                        } else {
                            MipFilter::None
                        },
                        wrap: if c.repeat { Wrap::Repeat } else { Wrap::Clamp },
                    },
                )
            }),
            perspective: [
                Perspective::Affine,
                Perspective::Exact,
                Perspective::Spans(4),
                Perspective::Spans(16),
            ][c.perspective as usize],
            fog: c.fog.then_some(Fog {
                color: [90, 80, 70],
                start: 600.0,
                end: 1500.0,
            }),
            ..RenderState::default()
        };
        let m = glam::dcamera::rh::proj::directx::perspective(1.1, 75.0 / 53.0, 100.0, 3000.0)
            * glam::dcamera::rh::view::look_at_mat4(
                DVec3::new(0.0, 0.0, 1000.0),
                DVec3::ZERO,
                DVec3::Y,
            )
            * DMat4::IDENTITY;
        let transform = Transform::new(m).unwrap();
        let n = c.vertices.len() / 3 * 3;
        let indices: Vec<u32> = (0..n as u32).collect();
        let mut r = Rasterizer::with_threads(1).with_tile_size(c.tile);
        let mut stats = DrawStats::default();
        let mut batch = r.batch(&mut fb);
        for part in indices.chunks(n.div_ceil(3).max(3) / 3 * 3) {
            let mesh = Mesh {
                vertices: &c.vertices,
                indices: Indices::U32(part),
                topology: Topology::TriangleList,
            };
            stats += batch.draw(&mesh, &transform, &state).unwrap();
        }
        stats += batch.finish();
        let depth = match fb.depth() {
            crate::DepthBuffer::None => vec![],
            crate::DepthBuffer::D16(d) => d.iter().flat_map(|v| v.to_le_bytes()).collect(),
            crate::DepthBuffer::D32(d) => d.iter().flat_map(|v| v.to_le_bytes()).collect(),
        };
        (fb.to_rgba_image().into_raw(), depth, stats)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        /// The row step with the colour stage in lanes (and the small-triangle loop) give the
        /// bytes of the scalar row loop they replaced, pixel for pixel, in every state.
        #[test]
        fn lanes_give_the_bytes_of_the_scalar_row_loop(c in case()) {
            let textures = textures();
            let fast = draw(&c, &textures);
            let scalar = reference::with(|| draw(&c, &textures));
            prop_assert_eq!(fast.2, scalar.2);
            prop_assert!(fast.1 == scalar.1, "depth differs");
            prop_assert!(fast.0 == scalar.0, "colour differs");
        }
    }
}
