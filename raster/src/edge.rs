//! Exact coverage: which pixel centres a triangle owns, row by row.
//!
//! A triangle in positive orientation is the set of points where all three edge functions
//! `E(p) = dx * (py - ay) - dy * (px - ax)` are positive, or zero on a top or left edge (the
//! top-left fill rule). For one row, an edge with `dy < 0` (a left edge) bounds the span from below
//! and owns its boundary; an edge with `dy > 0` (a right edge) bounds it from above and does not; a
//! horizontal edge is a top edge (owns its row) or a bottom edge (does not). Each bound is
//! `ceil(N / K)` of integers that change by a constant per row, so an integer DDA with a remainder
//! steps it exactly: the spans are those of per-pixel edge functions, bit for bit, with no
//! per-pixel test. Two triangles sharing an edge see it with opposite `dy`, so each centre on it
//! belongs to exactly one of them.
//!
//! Edges are set up once per triangle, as `EdgeFn`s with the rule's bias folded in. Consecutive
//! triangles of a strip share an edge, walked in opposite directions; the second takes it from the
//! first by `EdgeFn::reversed` instead of setting it up again.

use crate::fixed_point::{SUBPIXEL_BITS, SUBPIXEL_HALF, SUBPIXEL_ONE, ceil_div, floor_div};

/// One edge's function with the fill rule folded in: the pixel centre at sub-pixel `(x, y)` lies
/// on the owned side when `F(x, y) = c + dx * y - dy * x > 0`.
///
/// `F` is the edge function `E = dx * (y - ay) - dy * (x - ax)` plus the top-left bias (1 on a top
/// or left edge, 0 otherwise), so `F > 0` is exactly `E > 0`, or `E = 0` on a top or left edge.
/// Walked the other way round (as the next triangle of a strip sees their shared edge), `E`
/// negates and exactly one of the two directions is top or left: `c' = 1 - c`, with no
/// multiplication (see `reversed`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct EdgeFn {
    /// `|dx|, |dy| < 2^25` inside the guard band.
    dx: i32,
    dy: i32,
    /// `|c| < 2^51`.
    c: i64,
}

impl EdgeFn {
    /// The edge from `a` to `b` (sub-pixels, inside the guard band).
    #[inline]
    pub fn new(a: [i64; 2], b: [i64; 2]) -> Self {
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let top_left = dy < 0 || (dy == 0 && dx > 0);
        Self {
            dx: dx as i32,
            dy: dy as i32,
            c: dy * a[0] - dx * a[1] + top_left as i64,
        }
    }

    /// The same (non-degenerate) edge from `b` to `a`: what `EdgeFn::new(b, a)` computes.
    #[inline]
    pub fn reversed(self) -> Self {
        Self {
            dx: -self.dx,
            dy: -self.dy,
            c: 1 - self.c,
        }
    }

    /// `F` at the sub-pixel point `(x, y)`.
    #[inline]
    fn at(&self, x: i64, y: i64) -> i64 {
        self.c + self.dx as i64 * y - self.dy as i64 * x
    }

    /// For an edge with `dy != 0`, a DDA of the column bound at row `py`: the first owned column
    /// of a left edge (`dy < 0`), one past the last of a right edge (`dy > 0`), both `ceil(N / K)`.
    ///
    /// With `F0 = F(HALF, yc)` and `K = |dy| * ONE`, `F` at column `x` is `F0 - dy * ONE * x`. A
    /// right edge owns `x < F0 / K`, that is `x < ceil(F0 / K)`; a left edge owns `K x > -F0`, that
    /// is `x >= ceil((1 - F0) / K)`. Walked the other way, `F0` becomes `1 - F0`: both sides of a
    /// shared edge compute the same bound, so a centre on it belongs to exactly one of them.
    fn stepper(&self, py: i64) -> Stepper {
        let (dx, dy) = (self.dx as i64, self.dy as i64);
        let k = dy.abs() * SUBPIXEL_ONE;
        let f0 = self.at(SUBPIXEL_HALF, py * SUBPIXEL_ONE + SUBPIXEL_HALF);
        let (n, step) = if dy < 0 {
            (1 - f0, -dx * SUBPIXEL_ONE)
        } else {
            (f0, dx * SUBPIXEL_ONE)
        };
        let q = ceil_div(n, k);
        Stepper {
            q,
            rem: q * k - n,
            k,
            step_q: step.div_euclid(k),
            step_rem: step.rem_euclid(k),
        }
    }
}

/// Integer DDA for `q = ceil(N / K)`, with `rem = q * K - N` in `0..K`.
#[derive(Clone, Copy, Debug, Default)]
struct Stepper {
    q: i64,
    rem: i64,
    k: i64,
    step_q: i64,
    step_rem: i64,
}

impl Stepper {
    #[inline]
    fn next_row(&mut self) {
        // N' = N + step_q * K + step_rem; the ceiling moves up one more when step_rem > rem.
        if self.step_rem > self.rem {
            self.q += self.step_q + 1;
            self.rem += self.k - self.step_rem;
        } else {
            self.q += self.step_q;
            self.rem -= self.step_rem;
        }
    }
}

/// A triangle's owned pixels: its three edge functions, set up once (a strip triangle takes the
/// edge it shares with its predecessor from it, reversed), and the rows it owns.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Coverage {
    /// Edges `v0 -> v1`, `v1 -> v2`, `v2 -> v0` of the positively oriented triangle.
    edges: [EdgeFn; 3],
    /// First row.
    pub row_start: i32,
    /// One past the last row.
    pub row_end: i32,
    /// For a triangle within `SMALL x SMALL` pixels, the columns of its bounding box: it is
    /// walked by edge functions over them instead of by DDAs (decided once, at set-up).
    small_cols: Option<[i32; 2]>,
}

impl Coverage {
    /// The edge functions of the triangle `v` (sub-pixel x, y) with positive signed area, taking
    /// edge `shared.0` (from `v[i]` to `v[i + 1]`) ready-made when given.
    #[inline]
    pub fn edges(v: [[i64; 2]; 3], shared: Option<(usize, EdgeFn)>) -> [EdgeFn; 3] {
        let new = |i: usize| EdgeFn::new(v[i], v[(i + 1) % 3]);
        match shared {
            None => [new(0), new(1), new(2)],
            Some((0, e)) => [e, new(1), new(2)],
            Some((1, e)) => [new(0), e, new(2)],
            Some((_, e)) => [new(0), new(1), e],
        }
    }

    /// Coverage of the triangle `v` (sub-pixel x, y) with positive signed area
    /// `(v1 - v0) x (v2 - v0) > 0` and edge functions `edges` (see `Coverage::edges`), limited to
    /// rows `rows.0 .. rows.1`. `None` when it owns no row.
    pub fn new(v: [[i64; 2]; 3], edges: [EdgeFn; 3], rows: (i64, i64)) -> Option<Self> {
        let ymin = v.iter().map(|p| p[1]).min().expect("3 vertices");
        let ymax = v.iter().map(|p| p[1]).max().expect("3 vertices");
        // A horizontal edge with dx < 0 has the triangle above it: a bottom edge, which does not
        // own its row.
        let bottom_edge = edges.iter().any(|e| e.dy == 0 && e.dx < 0);
        // Rows whose centre yc satisfies ymin <= yc <= ymax (yc < ymax under a bottom edge).
        let first = ceil_div(ymin - SUBPIXEL_HALF, SUBPIXEL_ONE);
        let end = if bottom_edge {
            ceil_div(ymax - SUBPIXEL_HALF, SUBPIXEL_ONE)
        } else {
            floor_div(ymax - SUBPIXEL_HALF, SUBPIXEL_ONE) + 1
        };
        let (row_start, row_end) = (first.max(rows.0), end.min(rows.1));
        let xmin = v.iter().map(|p| p[0]).min().expect("3 vertices") >> SUBPIXEL_BITS;
        let xmax = v.iter().map(|p| p[0]).max().expect("3 vertices") >> SUBPIXEL_BITS;
        let small =
            xmax - xmin < SMALL && (ymax >> SUBPIXEL_BITS) - (ymin >> SUBPIXEL_BITS) < SMALL;
        (row_start < row_end).then_some(Coverage {
            edges,
            row_start: row_start as i32,
            row_end: row_end as i32,
            small_cols: small.then_some([xmin as i32, xmax as i32 + 1]),
        })
    }

    /// Calls `span(y, x_start, x_end)` for every row from `from` (clamped into the row range) to
    /// `to`, with `x_start..x_end` clamped to `cols`; empty spans are skipped.
    #[inline]
    pub fn for_each_span(
        &self,
        from: i64,
        to: i64,
        cols: (i64, i64),
        span: impl FnMut(i64, i64, i64),
    ) {
        let (start, end) = (
            (self.row_start as i64).max(from),
            (self.row_end as i64).min(to),
        );
        if start >= end {
            return;
        }
        if let Some([x0, x1]) = self.small_cols {
            self.walk_small(
                start,
                end,
                (cols.0.max(x0 as i64), cols.1.min(x1 as i64)),
                span,
            );
        } else {
            self.walk_dda(start, end, cols, span);
        }
    }

    /// Small triangles: evaluate the edge functions at every pixel of the bounding box, with no
    /// division and no data-dependent branch. Within `SMALL` pixels each edge value fits in i32
    /// (`|F| < 2 * (SMALL * 256)^2 + 1 < 2^25`), so a row's lanes are computed side by side.
    #[inline]
    fn walk_small(
        &self,
        start: i64,
        end: i64,
        cols: (i64, i64),
        mut span: impl FnMut(i64, i64, i64),
    ) {
        if cols.0 >= cols.1 {
            return;
        }
        let xc = cols.0 * SUBPIXEL_ONE + SUBPIXEL_HALF;
        let yc = start * SUBPIXEL_ONE + SUBPIXEL_HALF;
        // F at the first pixel of each row; steps per pixel and per row.
        let mut row = self.edges.map(|e| e.at(xc, yc) as i32);
        let step_x = self.edges.map(|e| -e.dy * SUBPIXEL_ONE as i32);
        let step_y = self.edges.map(|e| e.dx * SUBPIXEL_ONE as i32);
        let columns = (1u32 << (cols.1 - cols.0)) - 1;
        for y in start..end {
            // One bit per pixel inside all three edges; the set bits are contiguous because the
            // triangle is convex.
            let mut inside = 0u32;
            for i in 0..SMALL as i32 {
                let lane = |k: usize| row[k] + i * step_x[k] > 0;
                inside |= ((lane(0) & lane(1) & lane(2)) as u32) << i;
            }
            inside &= columns;
            if inside != 0 {
                let x0 = cols.0 + inside.trailing_zeros() as i64;
                let x1 = cols.0 + (32 - inside.leading_zeros()) as i64;
                span(y, x0, x1);
            }
            for k in 0..3 {
                row[k] += step_y[k];
            }
        }
    }

    /// Wide triangles: per edge, an exact DDA of the span bound.
    #[inline]
    fn walk_dda(
        &self,
        start: i64,
        end: i64,
        cols: (i64, i64),
        mut span: impl FnMut(i64, i64, i64),
    ) {
        let mut l = [Stepper::default(); 2];
        let mut r = [Stepper::default(); 2];
        let (mut nl, mut nr) = (0, 0);
        for e in &self.edges {
            if e.dy < 0 {
                l[nl] = e.stepper(start);
                nl += 1;
            } else if e.dy > 0 {
                r[nr] = e.stepper(start);
                nr += 1;
            }
        }
        debug_assert!(nl >= 1 && nr >= 1, "positive area has both sides");
        for y in start..end {
            let mut x0 = cols.0;
            for s in &mut l[..nl] {
                x0 = x0.max(s.q);
                s.next_row();
            }
            let mut x1 = cols.1;
            for s in &mut r[..nr] {
                x1 = x1.min(s.q);
                s.next_row();
            }
            if x0 < x1 {
                span(y, x0, x1);
            }
        }
    }
}

/// Triangles whose bounding box spans fewer than this many pixels each way are walked by edge
/// functions instead of DDAs.
const SMALL: i64 = 16;

#[cfg(test)]
mod tests {
    use super::*;

    const S: i64 = SUBPIXEL_ONE;

    /// Reference: the per-pixel edge-function test with the top-left rule.
    fn owns(v: [[i64; 2]; 3], px: i64, py: i64) -> bool {
        let (x, y) = (px * S + S / 2, py * S + S / 2);
        (0..3).all(|i| {
            let (a, b) = (v[i], v[(i + 1) % 3]);
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let e = dx * (y - a[1]) - dy * (x - a[0]);
            e > 0 || (e == 0 && (dy < 0 || (dy == 0 && dx > 0)))
        })
    }

    fn oriented(mut v: [[i64; 2]; 3]) -> [[i64; 2]; 3] {
        let area =
            (v[1][0] - v[0][0]) * (v[2][1] - v[0][1]) - (v[2][0] - v[0][0]) * (v[1][1] - v[0][1]);
        if area < 0 {
            v.swap(1, 2);
        }
        v
    }

    fn spans(v: [[i64; 2]; 3]) -> Vec<(i64, i64)> {
        let v = oriented(v);
        let mut out = vec![];
        if let Some(c) = Coverage::new(v, Coverage::edges(v, None), (-100, 100)) {
            c.for_each_span(-100, 100, (-100, 100), |y, a, b| {
                out.extend((a..b).map(|x| (x, y)))
            });
        }
        out
    }

    fn brute(v: [[i64; 2]; 3]) -> Vec<(i64, i64)> {
        let mut out = vec![];
        for y in -100..100 {
            for x in -100..100 {
                if owns(v, x, y) {
                    out.push((x, y));
                }
            }
        }
        out
    }

    #[test]
    fn spans_equal_the_per_pixel_edge_test_on_awkward_triangles() {
        let cases = [
            // Square split along its diagonal, edges on pixel centres.
            [[0, 0], [4 * S, 4 * S], [4 * S, 0]],
            [[0, 0], [0, 4 * S], [4 * S, 4 * S]],
            // Edges passing exactly through pixel centres.
            [[S / 2, S / 2], [5 * S / 2, 9 * S / 2], [9 * S / 2, S / 2]],
            // Sliver and sub-pixel.
            [[3, 7], [40 * S + 1, 3 * S + 5], [40 * S, 3 * S + 9]],
            [[10, 10], [100, 200], [200, 30]],
            // Negative coordinates.
            [[-7 * S, -3 * S], [-S + 3, 5 * S], [6 * S, -6 * S - 11]],
        ];
        for v in cases {
            assert_eq!(spans(v), brute(oriented(v)), "{v:?}");
        }
    }

    #[test]
    fn top_left_rule_on_a_unit_square_of_two_triangles() {
        // Pixel centre (0.5, 0.5) lies on the shared diagonal and on no outer edge's wrong side.
        let a = [[0, 0], [S, S], [S, 0]];
        let b = [[0, 0], [0, S], [S, S]];
        let n = spans(a).len() + spans(b).len();
        assert_eq!(n, 1, "the centre is owned exactly once");
        // A pixel-sized square with corners on pixel centres owns exactly one of its four corners.
        let c = [[S / 2, S / 2], [3 * S / 2, 3 * S / 2], [3 * S / 2, S / 2]];
        let d = [[S / 2, S / 2], [S / 2, 3 * S / 2], [3 * S / 2, 3 * S / 2]];
        let mut all = spans(c);
        all.extend(spans(d));
        assert_eq!(all, vec![(0, 0)], "top-left corner only");
    }

    proptest::proptest! {
        #[test]
        fn random_triangles_match_the_per_pixel_test(
            p in proptest::collection::vec((-40 * S..40 * S, -40 * S..40 * S), 3),
        ) {
            let v = [[p[0].0, p[0].1], [p[1].0, p[1].1], [p[2].0, p[2].1]];
            let area = (v[1][0] - v[0][0]) * (v[2][1] - v[0][1]) - (v[2][0] - v[0][0]) * (v[1][1] - v[0][1]);
            proptest::prop_assume!(area != 0);
            proptest::prop_assert_eq!(spans(v), brute(oriented(v)));
        }
    }

    proptest::proptest! {
        #[test]
        fn a_reversed_edge_is_the_edge_set_up_the_other_way(
            a in (-(1i64 << 24)..1 << 24, -(1i64 << 24)..1 << 24),
            b in (-(1i64 << 24)..1 << 24, -(1i64 << 24)..1 << 24),
        ) {
            proptest::prop_assume!(a != b);
            let (a, b) = ([a.0, a.1], [b.0, b.1]);
            proptest::prop_assert_eq!(EdgeFn::new(a, b).reversed(), EdgeFn::new(b, a));
        }

        #[test]
        fn a_strip_pair_sharing_its_edge_covers_like_two_fresh_triangles(
            p in proptest::collection::vec((-40 * S..40 * S, -40 * S..40 * S), 4),
        ) {
            // Strip a, b, c, d: triangles (a, b, c) and (c, b, d) share b -> c and c -> b.
            let area = |v: [[i64; 2]; 3]| {
                (v[1][0] - v[0][0]) * (v[2][1] - v[0][1]) - (v[2][0] - v[0][0]) * (v[1][1] - v[0][1])
            };
            let mut q = [p[0], p[1], p[2], p[3]].map(|(x, y)| [x, y]);
            if area([q[0], q[1], q[2]]) < 0 {
                // Mirrored, the strip keeps its shape and turns positive.
                q = q.map(|[x, y]| [-x, y]);
            }
            let [a, b, c, d] = q;
            let (first, second) = ([a, b, c], [c, b, d]);
            proptest::prop_assume!(area(first) > 0 && area(second) > 0);
            let shared = Coverage::edges(first, None)[1].reversed();
            let reused = Coverage::edges(second, Some((0, shared)));
            proptest::prop_assert_eq!(reused, Coverage::edges(second, None));
            let walk = |edges| {
                let mut out = vec![];
                if let Some(c) = Coverage::new(second, edges, (-100, 100)) {
                    c.for_each_span(-100, 100, (-100, 100), |y, a, b| out.push((y, a, b)));
                }
                out
            };
            proptest::prop_assert_eq!(walk(reused), walk(Coverage::edges(second, None)));
            // Every centre near the pair is owned by at most one of the two.
            let (mut one, mut two) = (spans(first), spans(second));
            one.append(&mut two);
            let n = one.len();
            one.sort();
            one.dedup();
            proptest::prop_assert_eq!(one.len(), n);
        }
    }

    #[test]
    fn row_window_matches_the_full_walk() {
        let v = [[3, 7], [40 * S + 1, 30 * S + 5], [-20 * S, 13 * S + 9]];
        let c = Coverage::new(v, Coverage::edges(v, None), (-100, 100)).unwrap();
        let mut full = vec![];
        c.for_each_span(-100, 100, (-100, 100), |y, a, b| full.push((y, a, b)));
        let mut banded = vec![];
        for band in (-100..100).step_by(7) {
            c.for_each_span(band, band + 7, (-100, 100), |y, a, b| {
                banded.push((y, a, b))
            });
        }
        assert_eq!(full, banded);
    }
}
