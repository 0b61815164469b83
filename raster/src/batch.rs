//! A batch of draws rasterized together: one frame's draw calls (the terrain engine makes
//! hundreds, one per tile) share the threads and the screen tiles instead of each paying for
//! its own.
//!
//! A draw call only assembles its triangles and copies the vertices they use (a lone
//! `Rasterizer::draw` reads them in place, and on several threads leaves a big mesh to be
//! assembled pass by pass in the flush). When enough triangles are pending (or the batch
//! ends) they are flushed pass by pass: each pass's vertices run the vertex stage once, set-up
//! runs in chunks on every thread and bins each triangle into the screen tiles it touches, and
//! every tile is drawn by one thread, its triangles in submission order. A
//! pixel's bytes depend only on the triangles that cover it, in that order: neither the thread
//! count nor the batching changes a byte.

use std::ops::Range;

use rayon::prelude::*;

use crate::RasterError;
use crate::bin::{TileGrid, tile_size};
use crate::clip::ClipVertex;
use crate::draw::{DrawStats, Rasterizer, Stages};
use crate::framebuffer::{ColorBuffer, DepthBuffer, Framebuffer};
use crate::isa::{Cpu, v3_twin};
use crate::lines::{LineState, LineStats};
use crate::matrix::Transform;
use crate::pipeline::fixed::FixedPipeline;
use crate::pipeline::float::FloatPipeline;
use crate::pipeline::{Attributes, Pipeline, TexMode, Viewport};
use crate::sampler::TexViews;
use crate::setup::{ChunkOut, DrawSetup, Transformed, by_draw, set_up};
use crate::shade::{ColorTile, DepthTile, DrawShade, Shade, TileTarget, raster_tile};
use crate::state::{Precision, Rect, RenderState};
use crate::tile_view::{TileView, split};
use crate::vertex::{Assembly, Mesh, Vertex, indices_in_range};

/// Pending triangles that trigger a flush after a draw.
const FLUSH_TRIANGLES: usize = 1 << 16;
/// Triangles set up and drawn per pass of a flush. A pass ends when its last tile is drawn, and
/// on several threads its last tiles leave the other threads waiting, once per pass: on scene
/// B's big draw, passes of 64k instead of 16k triangles make two threads 7-11% faster and one
/// thread no slower (`examples/pass_size.rs`, docs/raster.md). What they cost is memory: the
/// set-up data of two passes (the one drawn and the next, set up beside it), some 200 bytes a
/// triangle, 13 MB a pass at this size.
pub(crate) const PASS_TRIANGLES: usize = 64 * 1024;
/// Triangles per unit of parallel set-up work (or fewer, to give every thread two units). Each
/// unit bins its triangles into lists of its own, one per tile, which every tile then reads: on
/// scene B's passes of 64k triangles, units of 4,096 instead of 1,024 made two threads 2-7%
/// faster; 16,384 was level with 4,096 (docs/raster.md).
const SETUP_CHUNK: usize = 4096;
/// Vertices per unit of parallel vertex work.
const VERTEX_CHUNK: usize = 2048;
/// Below this many vertices the vertex stage runs on the calling thread.
const PARALLEL_MIN: usize = 4096;
/// Below this many triangles a flush is drawn on the calling thread: handing a smaller flush to
/// a second thread costs more than the thread saves (`examples/split_threshold.rs`, measured in
/// docs/raster.md: on a quiet machine a second thread lost below about 2,200 triangles at
/// 320x240 and paid 1.21x from 4,418).
pub(crate) const SPLIT_TRIANGLES: usize = 4096;

/// The geometry of the pending draws: copies of the vertices they use, and their triangles as
/// indices into those copies.
#[derive(Debug, Default)]
pub(crate) struct Pending {
    pub vertices: Vec<Vertex>,
    pub triangles: Vec<[u32; 3]>,
}

/// One pending draw: its state and where its vertices and triangles start.
struct PendingDraw<'t> {
    state: RenderState<'t>,
    attrs: Attributes<'t>,
    scissor: Rect,
    transform: Transform,
    views: TexViews<'t>,
    first_vertex: usize,
    first_triangle: usize,
}

/// Draws into one framebuffer that are rasterized together (see the module documentation).
///
/// Made by [`Rasterizer::batch`]. Each [`Batch::draw`] returns the triangles it assembled;
/// the triangles rasterized and the fragments written are counted when the batch ends
/// ([`Batch::finish`], or when it is dropped). The textures of a batch's draws are borrowed
/// until then.
pub struct Batch<'r, 't> {
    rasterizer: &'r mut Rasterizer,
    fb: &'r mut Framebuffer,
    draws: Vec<PendingDraw<'t>>,
    /// The vertices of the batch's only draw when it reads them where they are instead of a
    /// copy (`Batch::draw_in_place`).
    in_place: Option<&'t [Vertex]>,
    /// The batch's only draw when its triangles are assembled pass by pass in the flush.
    deferred: Option<Mesh<'t>>,
    precision: Precision,
    done: DrawStats,
}

impl Rasterizer {
    /// Starts a batch of draws into `fb`: the draws of a frame (the engine's tiles) rasterized
    /// together, with the same bytes as drawing them one by one.
    pub fn batch<'r, 't>(&'r mut self, fb: &'r mut Framebuffer) -> Batch<'r, 't> {
        Batch {
            rasterizer: self,
            fb,
            draws: Vec::new(),
            in_place: None,
            deferred: None,
            precision: Precision::Fixed,
            done: DrawStats::default(),
        }
    }
}

impl<'t> Batch<'_, 't> {
    /// Adds `mesh` to the batch. Returns its assembled triangles; its pixels are drawn later,
    /// in submission order. An index out of range fails the draw, and nothing of it is drawn.
    pub fn draw(
        &mut self,
        mesh: &Mesh,
        transform: &Transform,
        state: &RenderState<'t>,
    ) -> Result<DrawStats, RasterError> {
        self.add(mesh, None, transform, state)
    }

    /// `draw` for a mesh that outlives the batch: as the batch's first draw, its vertices are
    /// read where they are instead of copied (a 1280x720 frame's 220,900 vertices took 0.65 ms
    /// to copy, on every thread count). A mesh of more than one pass drawn on several threads
    /// is not assembled here but pass by pass in the flush, each pass beside the tiles of the
    /// one before (scene B's 439,922 triangles took about 1 ms to assemble, alone before any
    /// tile): its triangles are then counted in the batch's `finish`.
    pub(crate) fn draw_in_place(
        &mut self,
        mesh: &Mesh<'t>,
        transform: &Transform,
        state: &RenderState<'t>,
    ) -> Result<DrawStats, RasterError> {
        self.add(mesh, Some(*mesh), transform, state)
    }

    /// Adds a draw of `mesh`, which is `place` when it outlives the batch.
    fn add(
        &mut self,
        mesh: &Mesh,
        place: Option<Mesh<'t>>,
        transform: &Transform,
        state: &RenderState<'t>,
    ) -> Result<DrawStats, RasterError> {
        let scissor = Rect::scissor_on(state.scissor, self.fb.width(), self.fb.height())?;
        if state.precision != self.precision || self.deferred.is_some() {
            self.flush();
            self.precision = state.precision;
        }
        let r = &mut *self.rasterizer;
        let (first_vertex, first_triangle) = (r.pending.vertices.len(), r.pending.triangles.len());
        let in_place = place.is_some() && self.draws.is_empty();
        let empty = scissor.x0 == scissor.x1 || scissor.y0 == scissor.y1;
        let deferred = place.filter(|m| {
            in_place
                && !empty
                && m.vertices.len() <= m.indices.len()
                && m.indices.len() > r.pass_triangles
                && r.thread_count(m.indices.len()) > 1
                && indices_in_range(m)
        });
        let (triangles, left_in_place) = match deferred {
            Some(_) => (0, true),
            None => r.gather.append(mesh, &mut r.pending, in_place)?,
        };
        let stats = DrawStats {
            triangles: triangles as u64,
            ..DrawStats::default()
        };
        if deferred.is_none() && (triangles == 0 || empty) {
            r.pending.vertices.truncate(first_vertex);
            r.pending.triangles.truncate(first_triangle);
            return Ok(stats);
        }
        self.deferred = deferred;
        let has_depth = !matches!(self.fb.depth(), DepthBuffer::None);
        let attrs = Attributes::new(state, has_depth);
        let views = match state.texture {
            Some(b) if attrs.tex != TexMode::Off => TexViews::new(b.texture, b.sampler.wrap),
            _ => TexViews::None,
        };
        if left_in_place {
            self.in_place = place.map(|m| m.vertices);
        }
        self.draws.push(PendingDraw {
            state: *state,
            attrs,
            scissor,
            transform: *transform,
            views,
            first_vertex,
            first_triangle,
        });
        if r.pending.triangles.len() >= FLUSH_TRIANGLES {
            self.flush();
        }
        Ok(stats)
    }

    /// Draws the edges of `mesh`'s triangles as lines (see [`Rasterizer::draw_edges`]), over
    /// everything drawn before them in the batch.
    pub fn draw_edges(
        &mut self,
        mesh: &Mesh,
        transform: &Transform,
        state: &LineState,
    ) -> Result<LineStats, RasterError> {
        self.flush();
        self.rasterizer.draw_edges(self.fb, mesh, transform, state)
    }

    /// Draws what is pending and returns what the batch's draws rasterized: the triangles
    /// that reached the tiles and the fragments written (`triangles` is 0: each draw returned
    /// its own, but for a draw assembled in the flush, see `draw_in_place`).
    pub fn finish(mut self) -> DrawStats {
        self.flush();
        self.done
    }

    /// Draws every pending triangle.
    fn flush(&mut self) {
        if self.draws.is_empty() {
            return;
        }
        let r = &mut *self.rasterizer;
        let vertices = self.in_place.take().unwrap_or(&r.pending.vertices);
        let (source, size) = match self.deferred.take() {
            Some(mesh) => (Source::Mesh(mesh), mesh.indices.len()),
            None => (
                Source::Ready(&r.pending.triangles),
                r.pending.triangles.len(),
            ),
        };
        let geometry = (vertices, source);
        let threads = r.thread_count(size);
        let tile = r
            .tile_size
            .unwrap_or_else(|| tile_size(threads, self.fb.width(), self.fb.height()));
        let pass = r.pass_triangles;
        let (assembled, rasterized, fragments) = match self.precision {
            Precision::Fixed => flush_with::<FixedPipeline>(
                &mut r.fixed,
                geometry,
                &self.draws,
                self.fb,
                threads,
                (tile, pass, r.cpu),
            ),
            Precision::Float => flush_with::<FloatPipeline>(
                &mut r.float,
                geometry,
                &self.draws,
                self.fb,
                threads,
                (tile, pass, r.cpu),
            ),
        };
        self.done.triangles += assembled;
        self.done.rasterized += rasterized;
        self.done.fragments += fragments;
        r.pending.vertices.clear();
        r.pending.triangles.clear();
        self.draws.clear();
    }
}

impl Drop for Batch<'_, '_> {
    /// A batch dropped without [`Batch::finish`] still draws its pixels.
    fn drop(&mut self) {
        self.flush();
    }
}

/// Where a flush's triangles come from: the batch's assembled triangles, or the mesh of a lone
/// draw, assembled pass by pass (`Batch::draw_in_place`).
#[derive(Clone, Copy)]
enum Source<'a> {
    Ready(&'a [[u32; 3]]),
    Mesh(Mesh<'a>),
}

/// Set-up and tiles pass by pass: while the tiles draw one pass, the next pass's vertices are
/// transformed and its triangles set up beside them (and, for a `Source::Mesh`, assembled), so
/// a thread that runs out of tiles works on the next pass instead of waiting. Only the first
/// pass's vertex stage and set-up run before any tile. Returns the triangles assembled in the
/// flush (those of a `Source::Mesh`), the triangles rasterized and the fragments written.
fn flush_with<P: Shade>(
    stages: &mut Stages<P>,
    (vertices, source): (&[Vertex], Source<'_>),
    draws: &[PendingDraw],
    fb: &mut Framebuffer,
    threads: usize,
    (tile, pass, cpu): (u32, usize, Cpu),
) -> (u64, u64, u64) {
    let vp = Viewport {
        width: fb.width(),
        height: fb.height(),
    };
    let consts: Vec<P::Consts> = draws
        .iter()
        .map(|d| P::consts(&d.transform, &vp, d.state.fog))
        .collect();
    let grid = TileGrid::new(vp.width, vp.height, tile);
    let setups: Vec<DrawSetup> = draws
        .iter()
        .map(|d| DrawSetup {
            state: &d.state,
            attrs: &d.attrs,
            scissor: d.scissor,
        })
        .collect();
    let shades: Vec<DrawShade> = draws
        .iter()
        .map(|d| DrawShade {
            state: &d.state,
            attrs: &d.attrs,
            views: &d.views,
            cpu,
        })
        .collect();
    // Every element is written by the vertex stage before set-up reads it: only the elements a
    // longer flush adds are filled first, not the whole buffer on the calling thread.
    let Stages {
        transformed,
        passes,
        assembled,
    } = stages;
    transformed.truncate(vertices.len());
    transformed.resize(vertices.len(), Transformed::default());
    // The vertices before `done` are transformed. A pass needs those its triangles use: all
    // below one past the largest index of its and the earlier passes' triangles. A strip or a
    // list over a grid uses its vertices in order, so each pass transforms its own band of them.
    // Only worth its scan when later passes' vertices can be transformed beside the tiles.
    let overlap = threads > 1
        && match source {
            Source::Ready(t) => t.len() > pass,
            Source::Mesh(_) => true,
        };
    let mut done = 0;
    // The next pass's first triangle, and where a mesh's assembly stands.
    let (mut start, mut assembly) = (0, Assembly::default());
    // Takes the next pass's triangles (assembling them from a mesh), transforms the vertices
    // they use, then sets them up into `chunks` (as many as it needs, each a range of its own on
    // its own thread). Returns the chunks used and whether another pass follows.
    let mut prepare_pass = |chunks: &mut Vec<ChunkOut<P>>| -> (usize, bool) {
        // The pass is `range` of `tris`: of the ready triangles, or of the mesh's pass just
        // assembled (its only draw starts at 0).
        let (tris, range, more) = next_pass(source, start, pass, &mut assembly, assembled);
        start += range.len();
        if range.is_empty() {
            // A mesh's last indices may make only degenerate triangles.
            return (0, more);
        }
        let needed = if overlap {
            tris[range.clone()]
                .iter()
                .fold(done, |m, t| m.max(t[0].max(t[1]).max(t[2]) as usize + 1))
        } else {
            vertices.len()
        };
        if needed > done {
            vertex_stage::<P>(
                &mut transformed[done..needed],
                done,
                vertices,
                draws,
                &consts,
                (threads, cpu),
            );
            done = needed;
        }
        let transformed = &transformed[..done];
        let pieces = if threads > 1 {
            range
                .len()
                .div_ceil(SETUP_CHUNK)
                .max(2 * threads)
                .min(range.len())
        } else {
            1
        };
        if chunks.len() < pieces {
            chunks.resize_with(pieces, ChunkOut::default);
        }
        let piece = range.len().div_ceil(pieces);
        let set_up_piece = |k: usize, out: &mut ChunkOut<P>| {
            out.tris.clear();
            out.planes.clear();
            out.bins.reset(&grid);
            let from = range.start + k * piece;
            let part = from..(from + piece).min(range.end);
            by_draw(
                draws.len(),
                |d| draws[d].first_triangle,
                part,
                |d, part| {
                    set_up::<P>(
                        &tris[part],
                        (vertices, transformed),
                        d as u32,
                        &setups[d],
                        &consts[d],
                        &grid,
                        out,
                    )
                },
            );
        };
        if pieces > 1 {
            chunks[..pieces]
                .par_iter_mut()
                .enumerate()
                .for_each(|(k, out)| set_up_piece(k, out));
        } else {
            set_up_piece(0, &mut chunks[0]);
        }
        (pieces, more)
    };
    let [front, back] = passes;
    let (mut ready, mut next) = (front, back);
    let (mut used, mut more) = prepare_pass(ready);
    let (mut rasterized, mut fragments) = (0, 0);
    loop {
        let chunks = &ready[..used];
        rasterized += chunks.iter().map(|c| c.tris.len() as u64).sum::<u64>();
        let draw = |fb: &mut Framebuffer| raster_tiles::<P>(fb, chunks, &shades, &grid, threads);
        if !more {
            fragments += draw(fb);
            break;
        }
        let (drawn, set) = if threads > 1 {
            rayon::join(|| draw(fb), || prepare_pass(next))
        } else {
            (draw(fb), prepare_pass(next))
        };
        fragments += drawn;
        (used, more) = set;
        std::mem::swap(&mut ready, &mut next);
    }
    let assembled = match source {
        Source::Ready(_) => 0,
        Source::Mesh(_) => start as u64,
    };
    (assembled, rasterized, fragments)
}

/// The triangles of the pass that starts at triangle `start` (at most `pass`) as a range of a
/// slice, and whether another pass follows: a range of the ready triangles, or the next
/// triangles of a mesh, assembled into `assembled`.
fn next_pass<'a>(
    source: Source<'a>,
    start: usize,
    pass: usize,
    assembly: &mut Assembly,
    assembled: &'a mut Vec<[u32; 3]>,
) -> (&'a [[u32; 3]], Range<usize>, bool) {
    match source {
        Source::Ready(t) => {
            let end = (start + pass).min(t.len());
            (t, start..end, end < t.len())
        }
        Source::Mesh(mesh) => {
            assembled.clear();
            // Checked in `Batch::add` (`indices_in_range`): no index is out of range.
            let checked = assembly.resume(&mesh, |t| {
                assembled.push(t);
                assembled.len() < pass
            });
            debug_assert!(checked.is_ok());
            let more = checked.is_ok() && !assembly.done(&mesh);
            (&assembled[..], 0..assembled.len(), more)
        }
    }
}

/// The vertex stage of `vertices` (of one draw, its constants `c`) into `outs`. Runs the
/// x86-64-v3 twin where `cpu` allows (0.16M instructions less per PocketPC frame: its 128-bit
/// products and shifts take BMI2's forms).
fn transform<P: Pipeline>(
    c: &P::Consts,
    outs: &mut [Transformed<P>],
    vertices: &[Vertex],
    cpu: Cpu,
) {
    if cpu.v3() {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `cpu.v3()` holds only where the CPU has every feature the twin is built for.
        return unsafe { transform_v3::<P>(c, outs, vertices) };
    }
    transform_in::<P>(c, outs, vertices)
}

v3_twin! {
    /// `transform` built for x86-64-v3 (see `crate::isa`).
    fn transform_v3<P: Pipeline>(c: &P::Consts, outs: &mut [Transformed<P>], vertices: &[Vertex]) {
        transform_in::<P>(c, outs, vertices)
    }
}

/// The loop of `transform`, built into each of its twins.
#[inline(always)]
fn transform_in<P: Pipeline>(c: &P::Consts, outs: &mut [Transformed<P>], vertices: &[Vertex]) {
    for (o, v) in outs.iter_mut().zip(vertices) {
        let clip = P::clip(c, v);
        let outcode = clip.outcode(P::space(c));
        let screen = if outcode == 0 {
            P::project(c, &clip)
        } else {
            P::Screen::default()
        };
        *o = Transformed { outcode, screen };
    }
}

/// Runs the vertex stage over the pending vertices from `start` on into `out` (as many as it
/// holds), each with its draw's transform.
fn vertex_stage<P: Pipeline>(
    out: &mut [Transformed<P>],
    start: usize,
    vertices: &[Vertex],
    draws: &[PendingDraw],
    consts: &[P::Consts],
    (threads, cpu): (usize, Cpu),
) {
    let work = |start: usize, chunk: &mut [Transformed<P>]| {
        by_draw(
            draws.len(),
            |d| draws[d].first_vertex,
            start..start + chunk.len(),
            |d, part| {
                let outs = &mut chunk[part.start - start..part.end - start];
                transform::<P>(&consts[d], outs, &vertices[part], cpu);
            },
        )
    };
    if threads > 1 && out.len() >= PARALLEL_MIN {
        out.par_chunks_mut(VERTEX_CHUNK)
            .enumerate()
            .for_each(|(k, chunk)| work(start + k * VERTEX_CHUNK, chunk));
    } else {
        work(start, out);
    }
}

/// Draws every tile that has triangles, in parallel, each thread reusing its tile buffers.
/// Returns the fragments written.
fn raster_tiles<P: Shade>(
    fb: &mut Framebuffer,
    chunks: &[ChunkOut<P>],
    draws: &[DrawShade],
    grid: &TileGrid,
    threads: usize,
) -> u64 {
    let (color, depth) = fb.buffers_mut();
    let colors: Vec<ColorView> = match color {
        ColorBuffer::Rgb565(c) => split(c, grid).into_iter().map(ColorView::Rgb565).collect(),
        ColorBuffer::Rgba8888(c) => split(c, grid)
            .into_iter()
            .map(ColorView::Rgba8888)
            .collect(),
    };
    let depths: Vec<DepthView> = match depth {
        DepthBuffer::None => (0..grid.len()).map(|_| DepthView::None).collect(),
        DepthBuffer::D16(d) => split(d, grid).into_iter().map(DepthView::D16).collect(),
        DepthBuffer::D32(d) => split(d, grid).into_iter().map(DepthView::D32).collect(),
    };
    let tiles = colors
        .into_iter()
        .zip(depths)
        .enumerate()
        .filter(|(t, _)| chunks.iter().any(|c| !c.bins.list(*t).is_empty()));
    let draw = |spare: &mut TileBuffers,
                (t, (mut color, mut depth)): (usize, (ColorView, DepthView))| {
        let mut target = TileTarget {
            rect: grid.rect(t),
            color: color.load(spare),
            depth: depth.load(spare),
        };
        let fragments = raster_tile::<P>(t, chunks, draws, &mut target);
        color.store(target.color, spare);
        depth.store(target.depth, spare);
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

/// The allocations of the tiles a thread has drawn, for the next tile it loads.
#[derive(Default)]
struct TileBuffers {
    u16s: Vec<u16>,
    rgba: Vec<[u8; 4]>,
    u32s: Vec<u32>,
}

/// A tile of the colour buffer in the framebuffer's format.
enum ColorView<'a> {
    Rgb565(TileView<'a, u16>),
    Rgba8888(TileView<'a, [u8; 4]>),
}

impl ColorView<'_> {
    fn load(&mut self, spare: &mut TileBuffers) -> ColorTile {
        match self {
            ColorView::Rgb565(v) => ColorTile::Rgb565(v.load(std::mem::take(&mut spare.u16s))),
            ColorView::Rgba8888(v) => ColorTile::Rgba8888(v.load(std::mem::take(&mut spare.rgba))),
        }
    }

    fn store(&mut self, tile: ColorTile, spare: &mut TileBuffers) {
        match (self, tile) {
            (ColorView::Rgb565(v), ColorTile::Rgb565(t)) => spare.u16s = v.store(t),
            (ColorView::Rgba8888(v), ColorTile::Rgba8888(t)) => spare.rgba = v.store(t),
            _ => unreachable!("a tile goes back to its own buffer"),
        }
    }
}

/// A tile of the depth buffer in the framebuffer's format, if it has one.
enum DepthView<'a> {
    None,
    D16(TileView<'a, u16>),
    D32(TileView<'a, u32>),
}

impl DepthView<'_> {
    fn load(&mut self, spare: &mut TileBuffers) -> DepthTile {
        match self {
            DepthView::None => DepthTile::None,
            DepthView::D16(v) => DepthTile::D16(v.load(std::mem::take(&mut spare.u16s))),
            DepthView::D32(v) => DepthTile::D32(v.load(std::mem::take(&mut spare.u32s))),
        }
    }

    fn store(&mut self, tile: DepthTile, spare: &mut TileBuffers) {
        match (self, tile) {
            (DepthView::None, DepthTile::None) => {}
            (DepthView::D16(v), DepthTile::D16(t)) => spare.u16s = v.store(t),
            (DepthView::D32(v), DepthTile::D32(t)) => spare.u32s = v.store(t),
            _ => unreachable!("a tile goes back to its own buffer"),
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::{DMat4, DVec3};

    use super::{PASS_TRIANGLES, SPLIT_TRIANGLES};
    use crate::{
        ColorFormat, DepthFormat, Fog, Framebuffer, Indices, Mesh, Perspective, Precision,
        Rasterizer, RenderState, Sampler, Shading, Texture, TextureBinding, Topology, Transform,
        Vertex, Wrap,
    };

    /// Hills seen from low down: triangles from a fraction of a pixel far away to a hundred
    /// pixels near the eye, so runs cross tile edges, and strips through the near plane.
    fn scene() -> (Vec<Vertex>, Vec<Vec<u32>>, Texture, Transform) {
        let g = 48usize;
        let mut v = vec![];
        for j in 0..g {
            for i in 0..g {
                let h = ((i as f64 * 0.4).sin() * (j as f64 * 0.3).cos() * 300.0) as i32;
                let c = (100.0 + 90.0 * (i as f64 * 0.2 + j as f64 * 0.1).sin()) as u8;
                let light = if (i + j) % 7 == 0 {
                    [c, 200, 255 - c]
                } else {
                    [c; 3]
                };
                v.push(Vertex::new(
                    [i as i32 * 400 - 9600, h, j as i32 * 400 - 9600],
                    [i as f32 / 6.0, j as f32 / 6.0],
                    light,
                ));
            }
        }
        // One strip per row of cells, each its own draw when the scene is split.
        let strips = (0..g - 1)
            .map(|j| {
                (0..g)
                    .flat_map(|i| [(j * g + i) as u32, ((j + 1) * g + i) as u32])
                    .collect()
            })
            .collect();
        let texels = (0..32 * 32)
            .map(|k| {
                [
                    (k % 32 * 8) as u8,
                    (k / 32 * 8) as u8,
                    ((k * 37) % 256) as u8,
                    255,
                ]
            })
            .collect();
        let texture = Texture::from_rgba8(32, 32, texels).unwrap().with_mipmaps();
        let m = glam::dcamera::rh::proj::directx::perspective(1.2, 4.0 / 3.0, 50.0, 4e4)
            * glam::dcamera::rh::view::look_at_mat4(
                DVec3::new(300.0, 700.0, 9000.0),
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::Y,
            )
            * DMat4::IDENTITY;
        (v, strips, texture, Transform::new(m).unwrap())
    }

    /// The scene drawn with `tile`-pixel screen tiles and passes of `pass` triangles on
    /// `threads` threads, its strips grouped `per_draw` to a draw, all draws in one batch or
    /// (`batched` false) one by one.
    fn render(
        state: &RenderState,
        (tile, pass): (u32, usize),
        threads: usize,
        per_draw: usize,
        batched: bool,
    ) -> Framebuffer {
        let (v, strips, _, transform) = scene();
        on_threads(threads, (ColorFormat::Rgba8888, DepthFormat::D32), |fb| {
            // Split from the first triangle: a flush this small is otherwise drawn on one thread.
            let mut r = Rasterizer::new()
                .with_split_from(0)
                .with_pass_triangles(pass)
                .with_tile_size(tile);
            let draws: Vec<Vec<u32>> = strips
                .chunks(per_draw)
                .map(|group| group.join(&u32::MAX))
                .collect();
            fn mesh<'a>(v: &'a [Vertex], indices: &'a [u32]) -> Mesh<'a> {
                Mesh {
                    vertices: v,
                    indices: Indices::U32(indices),
                    topology: Topology::TriangleStrip,
                }
            }
            if batched {
                let mut batch = r.batch(fb);
                for d in &draws {
                    batch.draw(&mesh(&v, d), &transform, state).unwrap();
                }
                batch.finish();
            } else {
                for d in &draws {
                    r.draw(fb, &mesh(&v, d), &transform, state).unwrap();
                }
            }
        })
    }

    /// A 200x150 framebuffer in `formats`, cleared, after `f` drew into it on a pool of
    /// `threads` threads.
    fn on_threads(
        threads: usize,
        formats: (ColorFormat, DepthFormat),
        f: impl FnOnce(&mut Framebuffer) + Send,
    ) -> Framebuffer {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut fb = Framebuffer::new(200, 150, formats.0, formats.1).unwrap();
            fb.clear([10, 20, 30]);
            f(&mut fb);
            fb
        })
    }

    #[test]
    fn tiles_batches_and_threads_do_not_change_a_byte() {
        let (_, _, texture, _) = scene();
        for precision in [Precision::Fixed, Precision::Float] {
            for perspective in [
                Perspective::Spans(8),
                Perspective::Exact,
                Perspective::Affine,
            ] {
                let state = RenderState {
                    precision,
                    perspective,
                    shading: Shading::Gouraud,
                    texture: Some(TextureBinding::new(
                        &texture,
                        Sampler {
                            wrap: Wrap::Repeat,
                            ..Sampler::BILINEAR_MIPMAP
                        },
                    )),
                    fog: Some(Fog {
                        color: [10, 20, 30],
                        start: 3000.0,
                        end: 20000.0,
                    }),
                    ..RenderState::default()
                };
                // One tile for the whole screen, one pass, one thread, one draw: no run is
                // ever cut, and every triangle is set up before any is drawn.
                let whole = render(&state, (1 << 13, usize::MAX), 1, usize::MAX, true);
                assert!(
                    whole
                        .to_rgba_image()
                        .pixels()
                        .filter(|p| p.0 != [10, 20, 30, 255])
                        .count()
                        > 200 * 150 / 2,
                    "the scene covers most of the screen"
                );
                // The scene has 4,418 triangles: passes of 97 to 1,000 are set up while the
                // pass before them is drawn, and cut draws anywhere.
                for (tile, pass, threads, per_draw, batched) in [
                    (64, PASS_TRIANGLES, 1, usize::MAX, true),
                    (128, PASS_TRIANGLES, 2, 4, true),
                    (8, PASS_TRIANGLES, 1, 1, true),
                    (16, PASS_TRIANGLES, 2, 5, true),
                    (64, PASS_TRIANGLES, 4, 3, true),
                    (32, PASS_TRIANGLES, 2, 2, false),
                    (64, 1000, 1, usize::MAX, true),
                    (64, 300, 2, usize::MAX, true),
                    (64, 300, 2, usize::MAX, false),
                    (128, PASS_TRIANGLES, 1, usize::MAX, false),
                    (16, 97, 4, 3, true),
                    (32, 1000, 2, 2, false),
                ] {
                    assert!(
                        render(&state, (tile, pass), threads, per_draw, batched) == whole,
                        "{precision:?} {perspective:?}: tiles of {tile}, passes of {pass}, \
                         {threads} threads, {per_draw} strips a draw, batched {batched}"
                    );
                }
            }
        }
    }

    /// On several threads a pass transforms only the vertices up to the largest its triangles
    /// use, beside the tiles of the pass before it: strips out of order, whose passes use
    /// vertices far behind and far ahead of the earlier passes', draw as on one thread in one pass.
    #[test]
    fn passes_out_of_vertex_order_draw_the_same_bytes() {
        let (v, strips, _, transform) = scene();
        let order = (30..strips.len()).chain(10..30).rev().chain(0..10);
        let indices: Vec<u32> = order
            .map(|j| strips[j].clone())
            .collect::<Vec<_>>()
            .join(&u32::MAX);
        let mesh = Mesh {
            vertices: &v,
            indices: Indices::U32(&indices),
            topology: Topology::TriangleStrip,
        };
        let state = RenderState {
            shading: Shading::Gouraud,
            ..RenderState::default()
        };
        let draw = |threads: usize, pass: usize| {
            on_threads(threads, (ColorFormat::Rgb565, DepthFormat::D16), |fb| {
                let mut r = Rasterizer::new()
                    .with_split_from(0)
                    .with_pass_triangles(pass);
                r.draw(fb, &mesh, &transform, &state).unwrap();
            })
        };
        let whole = draw(1, usize::MAX);
        for (threads, pass) in [(2, 97), (2, 500), (3, 1000)] {
            assert!(
                draw(threads, pass) == whole,
                "{threads} threads, passes of {pass}"
            );
        }
    }

    /// On several threads a lone draw of more than one pass is assembled pass by pass in the
    /// flush: it counts its triangles, draws its bytes and fails on an index out of range (with
    /// nothing drawn) as one assembly on one thread does. The strip ends in degenerate triangles,
    /// so its last pass assembles none.
    #[test]
    fn a_draw_assembled_pass_by_pass_counts_draws_and_fails_as_one_assembly() {
        let (v, strips, _, transform) = scene();
        let mut indices = strips.join(&u32::MAX);
        indices.push(u32::MAX);
        indices.extend([5; 300]);
        let state = RenderState {
            shading: Shading::Gouraud,
            ..RenderState::default()
        };
        let draw = |threads: usize, pass: usize, indices: &[u32]| {
            let mut result = None;
            let fb = on_threads(threads, (ColorFormat::Rgb565, DepthFormat::D16), |fb| {
                let mut r = Rasterizer::new()
                    .with_split_from(0)
                    .with_pass_triangles(pass);
                let mesh = Mesh {
                    vertices: &v,
                    indices: Indices::U32(indices),
                    topology: Topology::TriangleStrip,
                };
                result = Some(r.draw(fb, &mesh, &transform, &state));
            });
            (result.unwrap(), fb)
        };
        let (one, whole) = draw(1, usize::MAX, &indices);
        let one = one.unwrap();
        assert_eq!(one.triangles, 4418);
        assert!(one.rasterized > 1000 && one.fragments > 10_000, "{one:?}");
        for (threads, pass) in [(2, 97), (2, 4418), (3, 1000)] {
            let (stats, fb) = draw(threads, pass, &indices);
            assert_eq!(stats.unwrap(), one, "{threads} threads, passes of {pass}");
            assert!(fb == whole, "{threads} threads, passes of {pass}");
        }
        // An index one past the vertices, after thousands of good triangles.
        let at = indices.len() - 400;
        indices[at] = v.len() as u32;
        let (failed, untouched) = draw(1, usize::MAX, &indices);
        assert!(failed.is_err());
        for (threads, pass) in [(2, 97), (3, 1000)] {
            let (result, fb) = draw(threads, pass, &indices);
            assert_eq!(result, failed, "{threads} threads, passes of {pass}");
            assert!(
                fb == untouched,
                "nothing drawn: {threads} threads, passes of {pass}"
            );
        }
        let image = untouched.to_rgba_image();
        let clear = image.get_pixel(0, 0).0;
        assert!(image.pixels().all(|p| p.0 == clear));
    }

    #[test]
    fn a_flush_too_small_to_split_stays_on_the_calling_thread() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        pool.install(|| {
            let r = Rasterizer::with_threads(2);
            assert_eq!(r.thread_count(SPLIT_TRIANGLES - 1), 1);
            assert_eq!(r.thread_count(SPLIT_TRIANGLES), 2);
            let r = Rasterizer::with_threads(2).with_split_from(10);
            assert_eq!((r.thread_count(9), r.thread_count(10)), (1, 2));
            assert_eq!(Rasterizer::with_threads(1).thread_count(1 << 20), 1);
        });
    }
}
