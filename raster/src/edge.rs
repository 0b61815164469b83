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

#[cfg(any(test, wide_vectors))]
use wide::i32x4;

use crate::fixed_point::{SUBPIXEL_BITS, SUBPIXEL_HALF, SUBPIXEL_ONE};

#[cfg(arm_neon)]
mod neon_rows;
#[cfg(arm_neon)]
pub(crate) use neon_rows::NeonRows;

/// A triangle's owned pixels: its snapped vertices and the pixel rectangle that can hold them.
/// Edges are rebuilt when its rows are walked, so a set-up triangle stays small.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Coverage {
    /// Vertices in sub-pixels, positive orientation; `|x|, |y| < 2^25` inside the guard band.
    v: [[i32; 2]; 3],
    /// The pixels it may own, inside the draw's scissor: columns `x0..x1`, rows `y0..y1` (the
    /// rows are exact: every one of them holds a pixel centre between the top and bottom vertex).
    pub rect: PixelRect,
    /// Within `SMALL x SMALL` pixels: walked by edge functions over its rectangle instead of by
    /// DDAs (decided once, at set-up).
    small: bool,
}

/// A rectangle of pixels, `x0..x1` by `y0..y1`, on screen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct PixelRect {
    pub x0: i32,
    pub y0: i32,
    pub x1: i32,
    pub y1: i32,
}

impl PixelRect {
    /// Index of pixel `(x, y)` (screen coordinates, inside) in the rectangle's pixels stored
    /// row after row, as a tile's buffers are.
    #[inline(always)]
    pub fn index(&self, y: i64, x: i64) -> usize {
        debug_assert!(
            (self.y0 as i64..self.y1 as i64).contains(&y)
                && (self.x0 as i64..self.x1 as i64).contains(&x)
        );
        (y - self.y0 as i64) as usize * (self.x1 - self.x0) as usize + (x - self.x0 as i64) as usize
    }
}

#[derive(Clone, Copy, Debug, Default)]
struct Edge {
    ax: i64,
    ay: i64,
    dx: i64,
    dy: i64,
}

impl Edge {
    /// The DDA of the bound `ceil(R / K)` from row `py`, whose centre is `yc`:
    /// `R = b (ax - 1/2) + a (yc - ay)` and `K = b ONE`, with `b = |dy|` and `a = sign(dy) dx`.
    /// With `ax - 1/2 = w ONE + f` (`f` in `0..ONE`), `R / K` is `w + (b f + a (yc - ay)) / K`
    /// and a row's step `a ONE / K` is `a / b`: quotients of numbers a 32-bit core divides in
    /// one word where they fit (`divmod_euclid`), and of no larger numbers elsewhere.
    fn stepper(&self, py: i64) -> Stepper {
        let (a, b) = (self.dy.signum() * self.dx, self.dy.abs());
        let k = b * SUBPIXEL_ONE;
        let yc = py * SUBPIXEL_ONE + SUBPIXEL_HALF;
        let base = self.ax - SUBPIXEL_HALF;
        let (whole, part) = (base >> SUBPIXEL_BITS, base & (SUBPIXEL_ONE - 1));
        // ceil(n / K) = -floor(-n / K), with `q K - n` the floor's remainder.
        let (floor, rem) = divmod_euclid(-(b * part + a * (yc - self.ay)), k);
        let (step_q, step_rem) = divmod_euclid(a, b);
        Stepper {
            q: whole - floor,
            rem,
            k,
            step_q,
            step_rem: step_rem * SUBPIXEL_ONE,
        }
    }
}

/// `(n.div_euclid(d), n.rem_euclid(d))` for `d > 0`: in i32 where both fit on a 32-bit core,
/// whose i64 division is a library call of about a hundred instructions.
#[inline(always)]
fn divmod_euclid(n: i64, d: i64) -> (i64, i64) {
    debug_assert!(d > 0);
    #[cfg(not(target_pointer_width = "64"))]
    if let (Ok(n), Ok(d)) = (i32::try_from(n), i32::try_from(d)) {
        return (i64::from(n.div_euclid(d)), i64::from(n.rem_euclid(d)));
    }
    (n.div_euclid(d), n.rem_euclid(d))
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
    /// `(v1 - v0) x (v2 - v0) > 0`, limited to the pixels of `clip`. `None` when it owns no row
    /// there (it may still own no pixel: a sliver between two pixel centres, see
    /// `Coverage::owns_no_pixel_of_its_row`).
    #[inline(always)]
    pub fn new(v: [[i64; 2]; 3], clip: PixelRect) -> Option<Self> {
        // In i32: inside the guard band every coordinate lies within 2^25, so each is one word
        // and the divisions by a pixel's sub-pixels are shifts (rounding down).
        let v = v.map(|p| p.map(|c| c as i32));
        let (one, half) = (SUBPIXEL_ONE as i32, SUBPIXEL_HALF as i32);
        let ymin = v[0][1].min(v[1][1]).min(v[2][1]);
        let ymax = v[0][1].max(v[1][1]).max(v[2][1]);
        // Rows whose centre yc satisfies ymin <= yc <= ymax, and yc < ymax under a bottom edge
        // (a horizontal edge with dx < 0 has the triangle above it and does not own its row),
        // which only matters when ymax lies on a row's centre.
        let first = (ymin - half + one - 1) >> SUBPIXEL_BITS;
        let mut end = ((ymax - half) >> SUBPIXEL_BITS) + 1;
        if (ymax - half) & (one - 1) == 0
            && (0..3).any(|i| v[i][1] == v[(i + 1) % 3][1] && v[(i + 1) % 3][0] < v[i][0])
        {
            end -= 1;
        }
        let (y0, y1) = (first.max(clip.y0), end.min(clip.y1));
        let xmin = v[0][0].min(v[1][0]).min(v[2][0]) >> SUBPIXEL_BITS;
        let xmax = v[0][0].max(v[1][0]).max(v[2][0]) >> SUBPIXEL_BITS;
        let small = xmax - xmin < SMALL as i32
            && (ymax >> SUBPIXEL_BITS) - (ymin >> SUBPIXEL_BITS) < SMALL as i32;
        // Owned pixel centres lie between the extreme vertices, so these columns hold them all.
        let (x0, x1) = (xmin.max(clip.x0), (xmax + 1).min(clip.x1));
        (y0 < y1 && x0 < x1).then_some(Coverage {
            v,
            rect: PixelRect { x0, y0, x1, y1 },
            small,
        })
    }

    /// True when the triangle `v` (its vertices, as given to `new`) is small, has one row and
    /// owns no pixel of it (`owns_a_pixel_of_row`); a triangle of several rows is not tested.
    /// The vertices are passed in because the set-up loop holds them in registers, where reading
    /// them back from `self` costs more (docs/optimisation-notes.md).
    ///
    /// Terrain far from the eye is slivers: on the peer benchmark's 1280x720 frame a fifth of
    /// the triangles with a row own no pixel, three quarters of those within one row. Dropped
    /// at set-up, they take no planes and no walk, which cost more than this test.
    #[inline(always)]
    pub fn owns_no_pixel_of_its_row(&self, v: &[[i64; 2]; 3]) -> bool {
        let r = self.rect;
        r.y1 - r.y0 == 1
            && self.small
            && !owns_a_pixel_of_row(v, r.y0 as i64, r.x0 as i64, r.x1 as i64)
    }

    /// The rectangle's first pixel `(x0, y0)`: where narrow attribute planes are based
    /// (`AttrPlane::on_grid`).
    #[inline]
    pub fn corner(&self) -> [i64; 2] {
        [self.rect.x0 as i64, self.rect.y0 as i64]
    }

    /// Vertex 0 in sub-pixels: the origin of the triangle's attribute planes.
    #[inline]
    pub fn origin(&self) -> [i64; 2] {
        self.v[0].map(i64::from)
    }

    /// Calls `span(y, x_start, x_end)` for every row of `from..to` that the triangle owns pixels
    /// in, with the row's whole run of owned pixels `x_start..x_end` (inside the rectangle, not
    /// cut to any tile): the same runs whatever the caller's window.
    #[inline]
    pub fn for_each_span(&self, from: i64, to: i64, span: impl FnMut(i64, i64, i64)) {
        let r = self.rect;
        let (start, end) = ((r.y0 as i64).max(from), (r.y1 as i64).min(to));
        if start >= end {
            return;
        }
        let cols = (r.x0 as i64, r.x1 as i64);
        if self.small {
            self.walk_small(start, end, cols, span);
        } else {
            self.walk_dda(start, end, cols, span);
        }
    }

    /// The three edges with the rule's bias: a pixel is owned when `E + bias > 0` for all three.
    #[inline]
    fn edges(&self) -> [(Edge, i64); 3] {
        let v = self.v.map(|p| [p[0] as i64, p[1] as i64]);
        let edge = |a: [i64; 2], b: [i64; 2]| {
            let e = Edge {
                ax: a[0],
                ay: a[1],
                dx: b[0] - a[0],
                dy: b[1] - a[1],
            };
            let top_left = e.dy < 0 || (e.dy == 0 && e.dx > 0);
            (e, top_left as i64)
        };
        [edge(v[0], v[1]), edge(v[1], v[2]), edge(v[2], v[0])]
    }

    /// True when the triangle is walked by edge functions (`small_rows`).
    #[inline]
    pub fn is_small(&self) -> bool {
        self.small
    }

    /// A small triangle's rows `from..to` (cut to its rectangle) as masks of owned columns (see
    /// `SmallRows`): the walk of `walk_small` for a caller that wants the row loop inline.
    #[inline(always)]
    pub fn small_rows(&self, from: i64, to: i64) -> SmallRows {
        #[cfg(wide_vectors)]
        return self.lane_rows(from, to);
        #[cfg(arm_neon)]
        return self.neon_rows(from, to);
        #[cfg(not(any(wide_vectors, arm_neon)))]
        return self.search_rows(from, to);
    }

    /// `small_rows` in lanes (`LaneRows`).
    #[cfg(any(test, wide_vectors))]
    #[inline(always)]
    fn lane_rows(&self, from: i64, to: i64) -> LaneRows {
        debug_assert!(self.small);
        let r = self.rect;
        let (start, end) = ((r.y0 as i64).max(from), (r.y1 as i64).min(to));
        let width = r.x1 - r.x0;
        debug_assert!((1..=SMALL as i32).contains(&width));
        // In i32 throughout: within `SMALL` pixels every term is below 2^25 (see `walk_small`).
        let one = SUBPIXEL_ONE as i32;
        let xc = r.x0 * one + SUBPIXEL_HALF as i32;
        let yc = start as i32 * one + SUBPIXEL_HALF as i32;
        let v = self.v;
        let groups = ((width + 3) / 4) as usize;
        let mut rows = LaneRows {
            lanes: [[i32x4::ZERO; 3]; 4],
            step: [i32x4::ZERO; 3],
            groups,
            columns: (1u32 << width) - 1,
            x0: r.x0 as i64,
            y: start,
            end,
        };
        // Each edge's value at the first column and its step to the next column, the edges in
        // lanes: the first group's columns are then three additions and one 4x4 transpose
        // (edges in lanes to columns in lanes), not twelve values placed lane by lane.
        let (mut row, mut s) = ([0i32; 4], [0i32; 4]);
        for i in 0..3 {
            let (a, b) = (v[i], v[(i + 1) % 3]);
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let top_left = dy < 0 || (dy == 0 && dx > 0);
            // `E + bias > 0` is `E + bias - 1 >= 0`: the sign bit says "outside".
            row[i] = dx * (yc - a[1]) - dy * (xc - a[0]) + top_left as i32 - 1;
            s[i] = -dy * one;
            rows.step[i] = i32x4::splat(dx * one);
        }
        let (row0, step) = (i32x4::new(row), i32x4::new(s));
        let row2 = row0 + step + step;
        let [e0, e1, e2, _] = i32x4::transpose([row0, row0 + step, row2, row2 + step]);
        rows.lanes[0] = [e0, e1, e2];
        for g in 1..groups {
            for (i, &s) in s[..3].iter().enumerate() {
                rows.lanes[g][i] = rows.lanes[0][i] + i32x4::splat(4 * g as i32 * s);
            }
        }
        rows
    }

    /// `small_rows` in scalar registers (`SearchRows`).
    #[cfg(any(test, not(any(wide_vectors, arm_neon))))]
    #[inline(always)]
    fn search_rows(&self, from: i64, to: i64) -> SearchRows {
        let (start, end, width) = self.small_span(from, to);
        SearchRows::new(
            self.small_edges(start),
            width,
            self.rect.x0 as i64,
            (start, end),
        )
    }

    /// `small_rows` in NEON lanes (`NeonRows`).
    #[cfg(arm_neon)]
    #[inline(always)]
    fn neon_rows(&self, from: i64, to: i64) -> NeonRows {
        let (start, end, width) = self.small_span(from, to);
        NeonRows::new(
            self.small_edges(start),
            width,
            self.rect.x0 as i64,
            start,
            end,
        )
    }

    /// A small triangle's rows `from..to` cut to its rectangle, and the rectangle's width.
    #[cfg(any(test, not(wide_vectors)))]
    #[inline(always)]
    fn small_span(&self, from: i64, to: i64) -> (i64, i64, u32) {
        debug_assert!(self.small);
        let r = self.rect;
        let width = r.x1 - r.x0;
        debug_assert!((1..=SMALL as i32).contains(&width));
        ((r.y0 as i64).max(from), (r.y1 as i64).min(to), width as u32)
    }

    /// A small triangle's edges in i32 (as `lane_rows`' lanes): `E + bias - 1` of each at the
    /// centre of the rectangle's first column in row `start`, and what each changes by from a
    /// column to the next and from a row to the next.
    #[cfg(any(test, not(wide_vectors)))]
    #[inline(always)]
    fn small_edges(&self, start: i64) -> ([i32; 3], [i32; 3], [i32; 3]) {
        let one = SUBPIXEL_ONE as i32;
        let xc = self.rect.x0 * one + SUBPIXEL_HALF as i32;
        let yc = start as i32 * one + SUBPIXEL_HALF as i32;
        let v = self.v;
        let (mut row, mut across, mut down) = ([0; 3], [0; 3], [0; 3]);
        for i in 0..3 {
            let (a, b) = (v[i], v[(i + 1) % 3]);
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let top_left = dy < 0 || (dy == 0 && dx > 0);
            row[i] = dx * (yc - a[1]) - dy * (xc - a[0]) + top_left as i32 - 1;
            across[i] = -dy * one;
            down[i] = dx * one;
        }
        (row, across, down)
    }

    /// Small triangles: evaluate the edge functions at every pixel of the rectangle, with no
    /// division and no data-dependent branch (`SmallRows`). Within `SMALL` pixels each edge value
    /// fits in i32 (`|E| < 2 * (SMALL * 256)^2 < 2^25`), so a row's pixels are tested in lanes, 4
    /// at a time.
    #[inline]
    fn walk_small(
        &self,
        start: i64,
        end: i64,
        cols: (i64, i64),
        mut span: impl FnMut(i64, i64, i64),
    ) {
        debug_assert_eq!(cols, (self.rect.x0 as i64, self.rect.x1 as i64));
        let mut rows = self.small_rows(start, end);
        while rows.y < rows.end {
            let y = rows.y;
            let inside = rows.next_mask();
            if inside != 0 {
                let x0 = rows.x0 + inside.trailing_zeros() as i64;
                let x1 = rows.x0 + (32 - inside.leading_zeros()) as i64;
                span(y, x0, x1);
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

/// True when the triangle `v` (small, positive orientation) owns a pixel of row `y` between
/// columns `x0` and `x1`: some column where no edge function is negative, found column by
/// column. The edges are `Coverage::small_rows`' (in i32: see `Coverage::walk_small`), written
/// out again, as a helper shared with `small_rows` makes the small loop dearer
/// (docs/optimisation-notes.md). Out of line: only triangles of one row ask.
#[inline(never)]
fn owns_a_pixel_of_row(v: &[[i64; 2]; 3], y: i64, x0: i64, x1: i64) -> bool {
    let one = SUBPIXEL_ONE as i32;
    let xc = x0 as i32 * one + SUBPIXEL_HALF as i32;
    let yc = y as i32 * one + SUBPIXEL_HALF as i32;
    // Each edge's `E + bias - 1` at the first column (negative: outside) and its step to the
    // next column.
    let edge = |a: [i64; 2], b: [i64; 2]| {
        let [a, b] = [a, b].map(|p| p.map(|c| c as i32));
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let top_left = (dy < 0) | ((dy == 0) & (dx > 0));
        (
            dx * (yc - a[1]) - dy * (xc - a[0]) + top_left as i32 - 1,
            -dy * one,
        )
    };
    let ((mut e0, s0), (mut e1, s1), (mut e2, s2)) =
        (edge(v[0], v[1]), edge(v[1], v[2]), edge(v[2], v[0]));
    for _ in x0..x1 {
        if (e0 | e1 | e2) >= 0 {
            return true;
        }
        (e0, e1, e2) = (e0 + s0, e1 + s1, e2 + s2);
    }
    false
}

/// A small triangle's rows, one mask of owned columns at a time (`next_mask`), with `x0` its
/// first column, `y` the current row and `end` the row past the last: in lanes where `wide`'s
/// `i32x4` is a vector (SSE2, NEON on aarch64, wasm's simd128), in NEON lanes of inline
/// assembly on 32-bit ARM with NEON (`NeonRows`), else in scalar registers, a column at a time
/// (`wide` builds an `i32x4` from four scalars there, the ARMv5TE among them, and four scalars
/// in memory per lane cost such a core more: `pocketpc_frames` on 32-bit ARM in
/// docs/raster.md).
#[cfg(wide_vectors)]
pub(crate) type SmallRows = LaneRows;
/// See the other `SmallRows`.
#[cfg(arm_neon)]
pub(crate) type SmallRows = NeonRows;
/// See the other `SmallRows`.
#[cfg(not(any(wide_vectors, arm_neon)))]
pub(crate) type SmallRows = SearchRows;

/// A small triangle's rows, one mask of owned columns at a time: the edge functions of a row's
/// pixels in groups of 4 `i32x4` lanes (one vector on SSE2 and NEON; a terrain triangle's
/// rectangle is mostly within 4 columns), stepped down the rows lane by lane (see
/// `Coverage::walk_small` for the bounds).
#[cfg(any(test, wide_vectors))]
pub(crate) struct LaneRows {
    /// `E + bias - 1` of the three edges at the current row's columns `4g..4g + 4` in group `g`:
    /// negative (sign bit set) where the pixel is outside.
    lanes: [[i32x4; 3]; 4],
    /// What each edge's lanes change by from a row to the next.
    step: [i32x4; 3],
    /// Groups of 4 columns the rectangle spans, `1..=4`.
    groups: usize,
    /// The rectangle's columns as bits.
    columns: u32,
    /// First column of the rectangle: bit `k` of a mask is column `x0 + k`.
    pub x0: i64,
    /// The current row.
    pub y: i64,
    /// The row past the last.
    pub end: i64,
}

#[cfg(any(test, wide_vectors))]
impl LaneRows {
    /// The owned columns of the current row as bits (bit `k` is column `x0 + k`), and a step to
    /// the next row. A pixel is owned when no edge's sign bit is set: one `or` of the three
    /// edges and one `movemask` per group of 4 columns.
    #[inline(always)]
    pub fn next_mask(&mut self) -> u32 {
        let step = self.step;
        let outside = |e: &mut [i32x4; 3]| {
            let bits = (e[0] | e[1] | e[2]).move_mask() as u32;
            for k in 0..3 {
                e[k] += step[k];
            }
            bits
        };
        let [g0, g1, g2, g3] = &mut self.lanes;
        let mut out = outside(g0);
        if self.groups > 1 {
            out |= outside(g1) << 4;
            if self.groups > 2 {
                out |= outside(g2) << 8;
                if self.groups > 3 {
                    out |= outside(g3) << 12;
                }
            }
        }
        self.y += 1;
        !out & self.columns
    }
}

/// A small triangle's rows in scalar registers: each row's run of owned columns from where its
/// edges cross the row, each found in as many halvings as the rectangle's width needs (see
/// `Coverage::walk_small` for the bounds).
///
/// Along a row an edge function is linear, so the columns outside an edge that rises across
/// the row (`E` grows from column to column) are a prefix of the row, and those inside an edge
/// that does not rise are a prefix too: a triangle's run starts past the longest outside
/// prefix of its rising edges and ends with the shortest inside prefix of the others. Every
/// triangle has an edge of each kind (its edges' `dy` sum to 0 and not all are 0), so edge 0
/// rises, edge 2 does not, and edge 1 goes either way. A halving is an add, a test and two
/// conditional moves, where testing every column costs three adds, the test and its bit.
///
/// Every row's mask is found when the rows are made, in a loop that holds only the edges: in
/// the row loop of its caller, which holds the attribute planes too, the edges' nine words went
/// to the stack and came back on every row.
/// `NeonRows` holds its masks alike; one type for both cost either core instructions
/// (docs/optimisation-notes.md).
#[cfg(any(test, not(any(wide_vectors, arm_neon))))]
pub(crate) struct SearchRows {
    /// The owned columns of row `start + k` as bits (bit `j` is column `x0 + j`).
    masks: [u16; SMALL as usize],
    /// The first row.
    start: i64,
    /// First column of the rectangle: bit `k` of a mask is column `x0 + k`.
    pub x0: i64,
    /// The current row.
    pub y: i64,
    /// The row past the last.
    pub end: i64,
}

#[cfg(any(test, not(any(wide_vectors, arm_neon))))]
impl SearchRows {
    /// Rows `start..end` (at most `SMALL`) of the small triangle whose edges have the values
    /// `row` at the first column of row `start` and the steps `across` and `down`
    /// (`Coverage::small_edges`), over `width` columns (at most 16) from `x0`.
    #[inline(always)]
    fn new(
        (row, across, down): ([i32; 3], [i32; 3], [i32; 3]),
        width: u32,
        x0: i64,
        (start, end): (i64, i64),
    ) -> Self {
        debug_assert!((1..=16).contains(&width) && end - start <= SMALL);
        // A rising edge first and one that does not rise last (see above).
        let rising = |i: usize| across[i] > 0;
        let first = (0..3).find(|&i| rising(i)).unwrap_or(0);
        let last = (0..3).find(|&i| !rising(i)).unwrap_or(2);
        let middle = 3 - first - last;
        let order = [first, middle, last];
        let edges = Edges {
            before: order.map(|i| row[i] - across[i]),
            across: order.map(|i| across[i]),
            down: order.map(|i| down[i]),
        };
        let mut masks = [0; SMALL as usize];
        let n = (end - start).clamp(0, SMALL) as usize;
        let masks_out = &mut masks[..n];
        // The halvings the width needs: a prefix capped at `2^halvings` columns is the prefix
        // itself wherever it matters, the columns past the rectangle being masked off.
        let columns = (1u32 << width) - 1;
        match (width, rising(middle)) {
            (..=4, true) => edges.masks::<2, true>(masks_out, columns),
            (..=4, false) => edges.masks::<2, false>(masks_out, columns),
            (..=8, true) => edges.masks::<3, true>(masks_out, columns),
            (..=8, false) => edges.masks::<3, false>(masks_out, columns),
            (_, true) => edges.masks::<4, true>(masks_out, columns),
            (_, false) => edges.masks::<4, false>(masks_out, columns),
        }
        Self {
            masks,
            start,
            x0,
            y: start,
            end,
        }
    }

    /// The owned columns of the current row as bits (bit `k` is column `x0 + k`), and a step to
    /// the next row.
    #[inline(always)]
    pub fn next_mask(&mut self) -> u32 {
        let mask = self.masks[(self.y - self.start) as usize & (SMALL as usize - 1)];
        self.y += 1;
        mask as u32
    }
}

const _: () = assert!((SMALL as usize).is_power_of_two());

/// `SearchRows`' three edges, a rising one first and one that does not rise last: `E + bias -
/// 1` one column left of the first row's first column, and their steps across and down.
#[cfg(any(test, not(any(wide_vectors, arm_neon))))]
struct Edges {
    before: [i32; 3],
    across: [i32; 3],
    down: [i32; 3],
}

#[cfg(any(test, not(any(wide_vectors, arm_neon))))]
impl Edges {
    /// The masks of the rows into `out`, one row after the other, cut to `columns`, each
    /// prefix found in `HALVINGS` halvings (`MIDDLE_RISES`: the middle edge rises, as the first
    /// does).
    #[inline(always)]
    fn masks<const HALVINGS: u32, const MIDDLE_RISES: bool>(
        mut self,
        out: &mut [u16],
        columns: u32,
    ) {
        for m in out {
            let [a, b, c] = self.before;
            let [sa, sb, sc] = self.across;
            let (mut first, mut end) = (
                prefix::<HALVINGS, true>(a, sa),
                prefix::<HALVINGS, false>(c, sc),
            );
            if MIDDLE_RISES {
                first = first.max(prefix::<HALVINGS, true>(b, sb));
            } else {
                end = end.min(prefix::<HALVINGS, false>(b, sb));
            }
            for (e, d) in self.before.iter_mut().zip(self.down) {
                *e += d;
            }
            // `first` and `end` are at most 16.
            *m = (((1u32 << end) - 1) & !((1u32 << first) - 1) & columns) as u16;
        }
    }
}

/// How many of the columns `0..2^HALVINGS` form the prefix where an edge is negative
/// (`OUTSIDE`, for an edge that rises across the row, `across > 0`) or not negative
/// (otherwise), from its value `before` one column left of column 0: the longest prefix `0..n`
/// with that sign at column `n - 1`, found in `HALVINGS` halvings and a last step.
#[cfg(any(test, not(any(wide_vectors, arm_neon))))]
#[inline(always)]
fn prefix<const HALVINGS: u32, const OUTSIDE: bool>(before: i32, across: i32) -> u32 {
    let holds = |e: i32| (e < 0) == OUTSIDE;
    // `at` is the edge at column `n - 1`, which holds for every `n` reached after column -1.
    let (mut at, mut n) = (before, 0);
    for step in [8, 4, 2, 1].into_iter().skip(4 - HALVINGS as usize) {
        let next = at + step as i32 * across;
        if holds(next) {
            (at, n) = (next, n + step);
        }
    }
    n + holds(at + across) as u32
}

/// Triangles whose bounding box spans fewer than this many pixels each way are walked by edge
/// functions instead of DDAs.
pub(crate) const SMALL: i64 = 16;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixed_point::ceil_div;

    const S: i64 = SUBPIXEL_ONE;
    const WINDOW: PixelRect = PixelRect {
        x0: -100,
        y0: -100,
        x1: 100,
        y1: 100,
    };

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

    proptest::proptest! {
        /// The stepper from split quotients (in words where they fit, on 32-bit cores) against
        /// `ceil(R / K)` and the step divided out in i64, for edges anywhere in the guard band
        /// and rows on and past their ends, each stepped a few rows.
        #[test]
        fn the_stepper_is_the_wide_division(
            a in (-(1i64 << 25)..1 << 25, -(1i64 << 25)..1 << 25),
            d in (-(1i64 << 25)..1 << 25, -(1i64 << 25)..1 << 25),
            short in proptest::bool::ANY,
            py in -(1i64 << 17)..1 << 17,
        ) {
            // Short edges (most of a frame's) as often as long ones.
            let (dx, dy) = if short { (d.0 >> 14, d.1 >> 14) } else { d };
            proptest::prop_assume!(dy != 0);
            let e = Edge { ax: a.0, ay: a.1, dx, dy };
            let k = dy.abs() * S;
            let step = dy.signum() * dx * S;
            let mut s = e.stepper(py);
            for row in py..py + 4 {
                let yc = row * S + S / 2;
                let r = dy.abs() * (e.ax - S / 2) + dy.signum() * dx * (yc - e.ay);
                let q = ceil_div(r, k);
                proptest::prop_assert_eq!((s.q, s.rem, s.k), (q, q * k - r, k));
                proptest::prop_assert_eq!(
                    (s.step_q, s.step_rem),
                    (step.div_euclid(k), step.rem_euclid(k))
                );
                s.next_row();
            }
        }
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
        if let Some(c) = Coverage::new(v, WINDOW) {
            c.for_each_span(-100, 100, |y, a, b| out.extend((a..b).map(|x| (x, y))));
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

    /// A walk's runs: `(y, x_start, x_end)`.
    type Runs = Vec<(i64, i64, i64)>;

    /// Runs of both walkers over the whole rectangle of `v` (oriented, non-degenerate).
    fn walks(v: [[i64; 2]; 3]) -> Option<(Runs, Runs)> {
        let c = Coverage::new(oriented(v), WINDOW)?;
        let r = c.rect;
        let (rows, cols) = ((r.y0 as i64, r.y1 as i64), (r.x0 as i64, r.x1 as i64));
        let (mut small, mut dda) = (vec![], vec![]);
        c.walk_small(rows.0, rows.1, cols, |y, a, b| small.push((y, a, b)));
        c.walk_dda(rows.0, rows.1, cols, |y, a, b| dda.push((y, a, b)));
        Some((small, dda))
    }

    /// Rows' first columns and masks of owned columns.
    type Masks = Vec<(i64, u32)>;

    /// The owned columns of each row of the small triangle `v` (oriented), as masks: in lanes
    /// and in scalar registers; both checked against the per-pixel test.
    fn masks(v: [[i64; 2]; 3]) -> Option<(Masks, Masks)> {
        let v = oriented(v);
        let c = Coverage::new(v, WINDOW).filter(|c| c.is_small())?;
        let (mut lanes, mut searched) = (
            c.lane_rows(i64::MIN, i64::MAX),
            c.search_rows(i64::MIN, i64::MAX),
        );
        let (mut a, mut b) = (vec![], vec![]);
        while lanes.y < lanes.end {
            a.push((lanes.x0, lanes.next_mask()));
        }
        while searched.y < searched.end {
            b.push((searched.x0, searched.next_mask()));
        }
        let r = c.rect;
        let brute: Masks = (r.y0 as i64..r.y1 as i64)
            .map(|y| {
                let bits = (r.x0 as i64..r.x1 as i64)
                    .filter(|&x| owns(v, x, y))
                    .fold(0, |m, x| m | 1 << (x - r.x0 as i64));
                (r.x0 as i64, bits)
            })
            .collect();
        assert_eq!(b, brute, "rows searched against the per-pixel test: {v:?}");
        #[cfg(arm_neon)]
        {
            let mut neon = c.neon_rows(i64::MIN, i64::MAX);
            let mut n = vec![];
            while neon.y < neon.end {
                n.push((neon.x0, neon.next_mask()));
            }
            assert_eq!(n, b, "NEON rows against the rows searched");
        }
        Some((a, b))
    }

    proptest::proptest! {
        /// The small-triangle path (edge functions in i32 lanes) and the general path (exact
        /// DDAs in i64) give the same runs for every triangle small enough for both, and the
        /// rows in scalar registers the masks of the rows in lanes.
        #[test]
        fn the_small_walk_equals_the_dda(
            base in (-60 * S..60 * S, -60 * S..60 * S),
            p in proptest::collection::vec((0..15 * S, 0..15 * S), 3),
        ) {
            let v = [0, 1, 2].map(|i| [base.0 + p[i].0, base.1 + p[i].1]);
            let area = (v[1][0] - v[0][0]) * (v[2][1] - v[0][1]) - (v[2][0] - v[0][0]) * (v[1][1] - v[0][1]);
            proptest::prop_assume!(area != 0);
            if let Some((small, dda)) = walks(v) {
                proptest::prop_assert_eq!(small, dda);
            }
            if let Some((lanes, columns)) = masks(v) {
                proptest::prop_assert_eq!(lanes, columns);
            }
        }

        /// Huge (to the guard band), sliver, edge-on and axis-aligned triangles own exactly
        /// the pixels of the per-pixel test inside the window.
        #[test]
        fn extreme_triangles_match_the_per_pixel_test(
            kind in 0u8..4,
            a in (-(1i64 << 24)..1 << 24, -(1i64 << 24)..1 << 24),
            b in (-(1i64 << 24)..1 << 24, -(1i64 << 24)..1 << 24),
            near in (-30 * S..30 * S, -30 * S..30 * S),
            t in -4i64..5,
        ) {
            let c = [near.0, near.1];
            let v = match kind {
                // Two far vertices and one in the window.
                0 => [[a.0, a.1], [b.0, b.1], c],
                // Nearly edge-on: the third vertex a few sub-pixels off the line through the
                // window vertex and a far one.
                1 => [[a.0, a.1], c, [c[0] + (a.0 - c[0]) / 1024 + t, c[1] + (a.1 - c[1]) / 1024 - t]],
                // A sliver along a pixel row or column.
                2 => [c, [c[0] + (a.0 >> 10), c[1] + t], [c[0] - (b.0 >> 12), c[1] + t + 1]],
                // Axis-aligned right triangle with edges on pixel centres.
                _ => [c, [c[0] + 7 * S, c[1]], [c[0], c[1] + (t.abs() + 1) * S]],
            };
            let area = (v[1][0] - v[0][0]) as i128 * (v[2][1] - v[0][1]) as i128
                - (v[2][0] - v[0][0]) as i128 * (v[1][1] - v[0][1]) as i128;
            proptest::prop_assume!(area != 0);
            proptest::prop_assert_eq!(spans(v), brute(oriented(v)));
        }
    }

    proptest::proptest! {
        /// A small triangle of one row is said to own no pixel exactly when the per-pixel test
        /// finds none; any other triangle is never said to own none.
        #[test]
        fn a_triangle_said_to_own_no_pixel_owns_none(
            base in (-60 * S..60 * S, -60 * S..60 * S),
            p in proptest::collection::vec((0..17 * S, 0..2 * S), 3),
            tall in 0i64..3,
        ) {
            let v = [0, 1, 2].map(|i| [base.0 + p[i].0, base.1 + p[i].1 * (1 + tall * i as i64)]);
            let area = (v[1][0] - v[0][0]) * (v[2][1] - v[0][1]) - (v[2][0] - v[0][0]) * (v[1][1] - v[0][1]);
            proptest::prop_assume!(area != 0);
            let v = oriented(v);
            if let Some(c) = Coverage::new(v, WINDOW) {
                let owns_none = brute(v).is_empty();
                if c.is_small() && c.rect.y1 - c.rect.y0 == 1 {
                    proptest::prop_assert_eq!(c.owns_no_pixel_of_its_row(&v), owns_none);
                } else {
                    proptest::prop_assert!(!c.owns_no_pixel_of_its_row(&v));
                }
            }
        }
    }

    #[test]
    fn slivers_between_pixel_centres_own_no_pixel() {
        // Thin triangles along a row, just above, on and just below its pixel centres.
        for dy in [-2, -1, 0, 1, 2] {
            let y = S / 2 + dy;
            let v = oriented([[0, y - 2], [9 * S, y], [4 * S, y + 2]]);
            let c = Coverage::new(v, WINDOW).expect("it spans a row's centre line");
            assert_eq!(c.rect.y1 - c.rect.y0, 1);
            assert_eq!(c.owns_no_pixel_of_its_row(&v), brute(v).is_empty(), "{v:?}");
            if dy == 0 {
                assert!(
                    !c.owns_no_pixel_of_its_row(&v),
                    "on the centre line it owns pixels"
                );
            }
        }
        // Between two pixel centres of a row: owns none.
        let v = oriented([[S / 2 + 1, 0], [3 * S / 2 - 1, S / 2], [S, S]]);
        let c = Coverage::new(v, WINDOW).unwrap();
        assert!(brute(v).is_empty() && c.owns_no_pixel_of_its_row(&v));
    }

    #[test]
    fn row_window_matches_the_full_walk() {
        let v = [[3, 7], [40 * S + 1, 30 * S + 5], [-20 * S, 13 * S + 9]];
        let c = Coverage::new(v, WINDOW).unwrap();
        let mut full = vec![];
        c.for_each_span(-100, 100, |y, a, b| full.push((y, a, b)));
        let mut banded = vec![];
        for band in (-100..100).step_by(7) {
            c.for_each_span(band, band + 7, |y, a, b| banded.push((y, a, b)));
        }
        assert_eq!(full, banded);
    }
}
