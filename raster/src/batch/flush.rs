//! A flush pass by pass: the vertex stage and set-up of the next pass beside the tiles of
//! the one before.

use std::ops::Range;

use rayon::prelude::*;

use super::PendingDraw;
use super::tiles::raster_tiles;
use super::vertex_stage::vertex_stage;
use crate::bin::TileGrid;
use crate::isa::Cpu;
use crate::pipeline::Viewport;
use crate::rasterizer::Stages;
use crate::setup::{ChunkOut, DrawSetup, Transformed, by_draw, set_up};
use crate::shade::{DrawShade, Shade};
use crate::surface::Surface;
use crate::vertex::{Assembly, Mesh, Vertex};

/// Triangles per unit of parallel set-up work (or fewer, to give every thread two units). Each
/// unit bins its triangles into lists of its own, one per tile, which every tile then reads;
/// smaller units make two threads slower, larger ones gain nothing (docs/optimisation-notes.md).
const SETUP_CHUNK: usize = 4096;
/// Where a flush's triangles come from: the batch's assembled triangles, or the mesh of a lone
/// draw, assembled pass by pass (`Batch::draw_in_place`).
#[derive(Clone, Copy)]
pub(super) enum Source<'a> {
    Ready(&'a [[u32; 3]]),
    Mesh(Mesh<'a>),
}

/// Set-up and tiles pass by pass: while the tiles draw one pass, the next pass's vertices are
/// transformed and its triangles set up beside them (and, for a `Source::Mesh`, assembled), so
/// a thread that runs out of tiles works on the next pass instead of waiting. Only the first
/// pass's vertex stage and set-up run before any tile. Returns the triangles assembled in the
/// flush (those of a `Source::Mesh`), the triangles rasterized and the fragments written.
pub(super) fn flush_with<P: Shade>(
    stages: &mut Stages<P>,
    (vertices, source): (&[Vertex], Source<'_>),
    draws: &[PendingDraw],
    fb: &mut Surface,
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
        let draw = |fb: &mut Surface| raster_tiles::<P>(fb, chunks, &shades, &grid, threads);
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
