//! Triangle set-up, shared by both pipelines: outcodes, clipping, culling, orientation, exact
//! coverage, the pipeline's attribute planes, and the bins of the tiles each triangle touches.
//!
//! A range of a batch's triangles is set up into one [`ChunkOut`]; ranges are independent, so
//! the chunks of a batch are set up on as many threads as there are, each triangle once.

use std::ops::Range;

use crate::bin::{Bins, TileGrid};
use crate::clip::{MAX_POLYGON, clip_triangle};
use crate::edge::{Coverage, PixelRect};
use crate::pipeline::{Attributes, Pipeline};
use crate::state::{CullMode, FrontFace, Rect, RenderState};
use crate::vertex::Vertex;

/// A vertex after the vertex stage: its outcode and (inside the guard band and the depth range)
/// its projection. Its clip-space position is not kept: the few triangles that need clipping
/// transform their vertices again, which costs less than storing every vertex's.
pub(crate) struct Transformed<P: Pipeline> {
    pub outcode: u8,
    pub screen: P::Screen,
}

impl<P: Pipeline> Clone for Transformed<P> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<P: Pipeline> Copy for Transformed<P> {}

impl<P: Pipeline> Default for Transformed<P> {
    fn default() -> Self {
        Self {
            outcode: 0,
            screen: P::Screen::default(),
        }
    }
}

/// What set-up needs of one draw.
pub(crate) struct DrawSetup<'a, 't> {
    pub state: &'a RenderState<'t>,
    pub attrs: &'a Attributes<'t>,
    pub scissor: Rect,
}

/// One set-up chunk: its triangles in submission order, the planes kept beside them, and the
/// tiles they touch.
pub(crate) struct ChunkOut<P: Pipeline> {
    pub tris: Vec<P::Triangle>,
    pub planes: Vec<P::Plane>,
    pub bins: Bins,
}

impl<P: Pipeline> Default for ChunkOut<P> {
    fn default() -> Self {
        Self {
            tris: Vec::new(),
            planes: Vec::new(),
            bins: Bins::default(),
        }
    }
}

/// Sets up `triangles` (indices into `vertices` and their stage's results `transformed`) of
/// draw `draw` into `out`, in order.
pub(crate) fn set_up<P: Pipeline>(
    triangles: &[[u32; 3]],
    (vertices, transformed): (&[Vertex], &[Transformed<P>]),
    draw: u32,
    setup: &DrawSetup,
    consts: &P::Consts,
    grid: &TileGrid,
    out: &mut ChunkOut<P>,
) {
    let s = setup.scissor;
    let clip_rect = PixelRect {
        x0: s.x0 as i32,
        y0: s.y0 as i32,
        x1: s.x1 as i32,
        y1: s.y1 as i32,
    };
    let cull = setup.state.cull;
    let ccw_front = setup.state.front_face == FrontFace::Ccw;
    let one = (setup, grid, clip_rect, cull, ccw_front);
    for t in triangles {
        let v = t.map(|i| &transformed[i as usize]);
        let and = v[0].outcode & v[1].outcode & v[2].outcode;
        let or = v[0].outcode | v[1].outcode | v[2].outcode;
        if and != 0 {
            continue;
        }
        if or == 0 {
            setup_one(v.map(|v| &v.screen), draw, one, out);
            continue;
        }
        let clip = t.map(|i| P::clip(consts, &vertices[i as usize]));
        let poly = clip_triangle(clip, or, P::space(consts));
        let mut screen = [P::Screen::default(); MAX_POLYGON];
        for (s, c) in screen.iter_mut().zip(&poly.vertices[..poly.len]) {
            *s = P::project(consts, c);
        }
        for k in 1..poly.len.saturating_sub(1) {
            setup_one([&screen[0], &screen[k], &screen[k + 1]], draw, one, out);
        }
    }
}

/// Sets up one triangle of draw `draw` (projected, inside the guard band) into `out`, unless it
/// has no area, is culled or owns no pixel inside the scissor `clip_rect`.
///
/// Always inlined: it is called once per triangle, where the call itself would be a
/// noticeable share of the set-up (docs/optimisation-notes.md).
#[inline(always)]
fn setup_one<P: Pipeline>(
    s: [&P::Screen; 3],
    draw: u32,
    (setup, grid, clip_rect, cull, ccw_front): (&DrawSetup, &TileGrid, PixelRect, CullMode, bool),
    out: &mut ChunkOut<P>,
) {
    let p = s.map(P::xy);
    // Inside the guard band coordinates lie within 2^25, so their differences are words and
    // each product one widening multiplication.
    let d = |i: usize, k: usize| (p[i][k] - p[0][k]) as i32 as i64;
    let area2 = d(1, 0) * d(2, 1) - d(2, 0) * d(1, 1);
    if area2 == 0 {
        return;
    }
    // Screen y points down, so a triangle counter-clockwise in NDC has negative area here.
    let front = (area2 < 0) == ccw_front;
    if (cull == CullMode::Back && !front) || (cull == CullMode::Front && front) {
        return;
    }
    let (s, p, area2) = if area2 < 0 {
        ([s[0], s[2], s[1]], [p[0], p[2], p[1]], -area2)
    } else {
        (s, p, area2)
    };
    if let Some(cov) = Coverage::new(p, clip_rect) {
        if cov.owns_no_pixel_of_its_row(&p) {
            return;
        }
        out.bins.insert(grid, cov.rect, out.tris.len() as u32);
        let t = P::triangle(s, area2, cov, setup.attrs, draw, &mut out.planes);
        out.tris.push(t);
    }
}

/// Calls `f(draw, part)` for the part of `range` that belongs to each draw, in order, where draw
/// `d`'s items start at `first(d)` (increasing, `first(0) == 0`) and run to the next draw's.
pub(crate) fn by_draw(
    draws: usize,
    first: impl Fn(usize) -> usize,
    range: Range<usize>,
    mut f: impl FnMut(usize, Range<usize>),
) {
    if range.is_empty() {
        return;
    }
    // The last draw that starts at or before the range.
    let (mut lo, mut hi) = (0, draws);
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if first(mid) <= range.start {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let (mut d, mut s) = (lo, range.start);
    while s < range.end {
        let end = if d + 1 < draws {
            first(d + 1).min(range.end)
        } else {
            range.end
        };
        if s < end {
            f(d, s..end);
        }
        s = end.max(s);
        d += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_split_at_draw_boundaries() {
        let firsts = [0, 4, 4, 10, 11];
        let parts = |r: Range<usize>| {
            let mut out = vec![];
            by_draw(firsts.len(), |d| firsts[d], r, |d, p| out.push((d, p)));
            out
        };
        assert_eq!(
            parts(0..20),
            vec![(0, 0..4), (2, 4..10), (3, 10..11), (4, 11..20)]
        );
        assert_eq!(parts(5..11), vec![(2, 5..10), (3, 10..11)]);
        assert_eq!(parts(3..4), vec![(0, 3..4)]);
        assert_eq!(parts(12..15), vec![(4, 12..15)]);
        assert!(parts(7..7).is_empty());
    }
}
