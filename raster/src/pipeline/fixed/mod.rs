//! The integer pipeline: what a device without an FPU runs, and the fast path everywhere.
//!
//! Vertex stage: exact i64 transform (see `matrix`), outcodes, projection with one reciprocal per
//! vertex (of a normalised `w`, `fixed_point::reciprocal`). Triangle setup: attribute planes from
//! one reciprocal of the area. Pixels: monomorphised row loops that step i64 accumulators (a
//! small triangle's in 32-bit words on a 32-bit core, `small::rows_of`).
//!
//! One file per job: `clip` (clip space, outcodes, cuts), `projection` (the vertex stage's
//! projection), `planes` (attribute planes), `triangle` (set-up), `division` (the row loops'
//! divisions) and `rows` (the row step).

use crate::edge::Coverage;
use crate::matrix::{FixedMat4, Transform};
use crate::pipeline::{Attributes, Pipeline, Viewport};
use crate::pixel::{DepthStorage, PixelFormat};
use crate::state::Fog;
use crate::vertex::Vertex;

mod clip;
mod division;
mod planes;
mod projection;
#[cfg(test)]
pub(crate) mod reference;
mod rows;
#[cfg(test)]
mod test_support;
mod triangle;

pub(crate) use clip::{FixedClip, FixedSpace};
pub(crate) use division::{divide, divide_in_range};
pub(crate) use planes::AttrPlane;
pub(crate) use projection::{FixedFog, FixedScreen};
pub(crate) use rows::{DepthTest, NarrowPlanes, RunPiece, WORDS, plane_offsets, run_fragments};
pub(crate) use triangle::FixedTriangle;

/// The integer pipeline's stages.
pub(crate) struct FixedPipeline;

/// What the fixed vertex stage of one draw needs.
pub(crate) struct FixedConsts {
    matrix: FixedMat4,
    vp: Viewport,
    space: FixedSpace,
    fog: Option<FixedFog>,
}

impl Pipeline for FixedPipeline {
    type Clip = FixedClip;
    type Screen = FixedScreen;
    type Triangle = FixedTriangle;
    type Plane = AttrPlane;
    type Consts = FixedConsts;

    fn consts(transform: &Transform, vp: &Viewport, fog: Option<Fog>) -> FixedConsts {
        FixedConsts {
            matrix: transform.fixed,
            vp: *vp,
            space: FixedSpace::new(vp),
            fog: fog.map(|f| FixedFog {
                start: transform.fixed.scale_length(f.start),
                end: transform.fixed.scale_length(f.end),
            }),
        }
    }

    fn space(c: &FixedConsts) -> &FixedSpace {
        &c.space
    }

    #[inline]
    fn clip(c: &FixedConsts, v: &Vertex) -> FixedClip {
        FixedClip::from_vertex(v, &c.matrix)
    }

    /// Always inlined into the vertex stage's loop: out of line, the call and its saved
    /// registers would be a measurable share of the vertex stage (docs/optimisation-notes.md).
    #[inline(always)]
    fn project(c: &FixedConsts, clip: &FixedClip) -> FixedScreen {
        FixedScreen::project(clip, &c.vp, c.fog)
    }

    #[inline]
    fn xy(s: &FixedScreen) -> [i64; 2] {
        s.xy
    }

    /// Inlined into the set-up loop on 64-bit cores, where the call per triangle costs more
    /// than the copies of the loop it saves; out of line on 32-bit ones, whose few registers the
    /// loop and the planes' 64-bit values then no longer share (fewer spills, fewer
    /// instructions a PocketPC frame).
    #[cfg_attr(target_pointer_width = "64", inline(always))]
    #[cfg_attr(not(target_pointer_width = "64"), inline(never))]
    fn triangle(
        v: [&FixedScreen; 3],
        area2: i64,
        coverage: Coverage,
        attrs: &Attributes,
        draw: u32,
        planes: &mut Vec<AttrPlane>,
    ) -> FixedTriangle {
        FixedTriangle::new(v, area2, coverage, attrs, draw, planes)
    }
}

/// One row's run of a triangle: it owns pixels `x0..x1` of row `y`, and `color` and `depth`
/// (empty without a depth test) hold pixels `xs..` of them (a tile's part of the run).
pub(crate) struct Span<'a, P: PixelFormat, D: DepthStorage> {
    pub y: i64,
    pub x0: i64,
    pub x1: i64,
    pub xs: i64,
    pub color: &'a mut [P::Pixel],
    pub depth: &'a mut [D::Value],
}
