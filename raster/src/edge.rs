//! Exact coverage: which pixel centres a triangle owns, row by row.
//!
//! A triangle in positive orientation is the set of points where all three edge functions
//! `E(p) = dx * (py - ay) - dy * (px - ax)` are positive, or zero on a top or left edge (the
//! top-left fill rule). For one row, an edge with `dy < 0` (a left edge) bounds the span from below
//! and owns its boundary; an edge with `dy > 0` (a right edge) bounds it from above and does not; a
//! horizontal edge is a top edge (owns its row) or a bottom edge (does not). Each bound is
//! `ceil(R / K)` of integers that change by a constant per row, so an integer DDA with a remainder
//! steps it exactly: the spans are those of per-pixel edge functions, bit for bit, with no
//! per-pixel test. Two triangles sharing an edge see it with opposite `dy`, so each centre on it
//! belongs to exactly one of them.

use crate::fixed_point::{SUBPIXEL_BITS, SUBPIXEL_HALF, SUBPIXEL_ONE, ceil_div, floor_div};

/// A triangle's owned pixels: its snapped vertices and the rows it owns. Edges are rebuilt when
/// its rows are walked, so a set-up triangle stays small.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Coverage {
    /// Vertices in sub-pixels, positive orientation; `|x|, |y| < 2^25` inside the guard band.
    v: [[i32; 2]; 3],
    /// First row.
    pub row_start: i32,
    /// One past the last row.
    pub row_end: i32,
    /// For a triangle within `SMALL x SMALL` pixels, the columns of its bounding box: it is
    /// walked by edge functions over them instead of by DDAs (decided once, at set-up).
    small_cols: Option<[i32; 2]>,
}

#[derive(Clone, Copy, Debug, Default)]
struct Edge {
    ax: i64,
    ay: i64,
    dx: i64,
    dy: i64,
}

impl Edge {
    /// `K` of the bound `ceil(R / K)`.
    #[inline]
    fn k(&self) -> i64 {
        self.dy.abs() * SUBPIXEL_ONE
    }

    /// `R` at row `py`.
    #[inline]
    fn r_at(&self, py: i64) -> i64 {
        let yc = py * SUBPIXEL_ONE + SUBPIXEL_HALF;
        self.dy.abs() * (self.ax - SUBPIXEL_HALF) + self.dy.signum() * self.dx * (yc - self.ay)
    }

    fn stepper(&self, py: i64) -> Stepper {
        let k = self.k();
        let r = self.r_at(py);
        let q = ceil_div(r, k);
        let step = self.dy.signum() * self.dx * SUBPIXEL_ONE;
        Stepper {
            q,
            rem: q * k - r,
            k,
            step_q: step.div_euclid(k),
            step_rem: step.rem_euclid(k),
        }
    }
}

/// Integer DDA for `q = ceil(R / K)`, with `rem = q * K - R` in `0..K`.
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
        // R' = R + step_q * K + step_rem; the ceiling moves up one more when step_rem > rem.
        if self.step_rem > self.rem {
            self.q += self.step_q + 1;
            self.rem += self.k - self.step_rem;
        } else {
            self.q += self.step_q;
            self.rem -= self.step_rem;
        }
    }
}

impl Coverage {
    /// Coverage of the triangle `v` (sub-pixel x, y) with positive signed area
    /// `(v1 - v0) x (v2 - v0) > 0`, limited to rows `rows.0 .. rows.1`. `None` when it owns no row.
    pub fn new(v: [[i64; 2]; 3], rows: (i64, i64)) -> Option<Self> {
        let ymin = v.iter().map(|p| p[1]).min().expect("3 vertices");
        let ymax = v.iter().map(|p| p[1]).max().expect("3 vertices");
        // A horizontal edge with dx < 0 has the triangle above it: a bottom edge, which does not
        // own its row.
        let bottom_edge =
            (0..3).any(|i| v[i][1] == v[(i + 1) % 3][1] && v[(i + 1) % 3][0] < v[i][0]);
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
        (row_start < row_end).then(|| Coverage {
            v: v.map(|p| p.map(|c| c as i32)),
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

    /// The three edges with the rule's bias: a pixel is owned when `E + bias > 0` for all three.
    #[inline]
    fn edges(&self) -> [(Edge, i64); 3] {
        [0, 1, 2].map(|i| {
            let (a, b) = (self.v[i].map(i64::from), self.v[(i + 1) % 3].map(i64::from));
            let e = Edge {
                ax: a[0],
                ay: a[1],
                dx: b[0] - a[0],
                dy: b[1] - a[1],
            };
            let top_left = e.dy < 0 || (e.dy == 0 && e.dx > 0);
            (e, top_left as i64)
        })
    }

    /// Small triangles: evaluate the edge functions at every pixel of the bounding box, with no
    /// division and no data-dependent branch. Within `SMALL` pixels each edge value fits in i32
    /// (`|E| < 2 * (SMALL * 256)^2 < 2^25`), so a row's lanes are computed side by side.
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
        let edges = self.edges();
        let xc = cols.0 * SUBPIXEL_ONE + SUBPIXEL_HALF;
        let yc = start * SUBPIXEL_ONE + SUBPIXEL_HALF;
        // E + bias at the first pixel of each row; steps per pixel and per row.
        let mut row =
            edges.map(|(e, bias)| (e.dx * (yc - e.ay) - e.dy * (xc - e.ax) + bias) as i32);
        let step_x = edges.map(|(e, _)| (-e.dy * SUBPIXEL_ONE) as i32);
        let step_y = edges.map(|(e, _)| (e.dx * SUBPIXEL_ONE) as i32);
        let width = cols.1 - cols.0;
        let columns = (1u32 << width) - 1;
        // Terrain triangles are a few pixels wide: half the lanes do for most of them.
        let half = width <= SMALL / 2;
        for y in start..end {
            let inside = if half {
                inside_lanes::<{ SMALL as usize / 2 }>(&row, &step_x)
            } else {
                inside_lanes::<{ SMALL as usize }>(&row, &step_x)
            } & columns;
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
        for (e, _) in self.edges() {
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

/// One bit per pixel of a row's first `N` columns that lies inside all three edges (`row`: edge
/// values at the first pixel, `step`: per pixel). The set bits are contiguous because the triangle
/// is convex.
#[inline]
fn inside_lanes<const N: usize>(row: &[i32; 3], step: &[i32; 3]) -> u32 {
    let mut inside = 0u32;
    for i in 0..N as i32 {
        let lane = |k: usize| row[k] + i * step[k] > 0;
        inside |= ((lane(0) & lane(1) & lane(2)) as u32) << i;
    }
    inside
}

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
        if let Some(c) = Coverage::new(v, (-100, 100)) {
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

    #[test]
    fn row_window_matches_the_full_walk() {
        let v = [[3, 7], [40 * S + 1, 30 * S + 5], [-20 * S, 13 * S + 9]];
        let c = Coverage::new(v, (-100, 100)).unwrap();
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
