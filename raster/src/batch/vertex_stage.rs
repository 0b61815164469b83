//! The vertex stage of a flush: every pending vertex transformed once, with its draw's
//! transform, in parallel chunks.

use rayon::prelude::*;

use super::PendingDraw;
use crate::clip::ClipVertex;
use crate::isa::{Cpu, v3_twin};
use crate::pipeline::Pipeline;
use crate::setup::{Transformed, by_draw};
use crate::vertex::Vertex;

/// Vertices per unit of parallel vertex work.
const VERTEX_CHUNK: usize = 2048;
/// Below this many vertices the vertex stage runs on the calling thread.
const PARALLEL_MIN: usize = 4096;
/// The vertex stage of `vertices` (of one draw, its constants `c`) into `outs`. Runs the
/// x86-64-v3 twin where `cpu` allows (its 128-bit products and shifts take BMI2's forms; what
/// it saves: docs/raster.md, *Where the time goes*).
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
pub(super) fn vertex_stage<P: Pipeline>(
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
