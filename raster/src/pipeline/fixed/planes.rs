//! Attribute planes: per-pixel gradients from one reciprocal of a triangle's area, in i64 for
//! small triangles and 128-bit products otherwise, and moved onto the pixel grid where narrow.

use super::projection::FixedScreen;
use crate::edge::Coverage;
use crate::fixed_point::{
    ATTR_FRAC_BITS, SUBPIXEL_BITS, SUBPIXEL_HALF, SUBPIXEL_ONE, normalise_positive, reciprocal,
    saturate_i64, shift_round,
};

/// An attribute as a plane over the triangle: per-pixel gradients and a base, all with
/// `ATTR_FRAC_BITS` extra fraction. The base is the value at the origin vertex, or, once the plane
/// is moved onto the pixel grid (`on_grid`), the value at the centre of pixel `(0, 0)`.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct AttrPlane {
    base: i64,
    pub(crate) dx: i64,
    pub(crate) dy: i64,
}

/// Gradients below this keep every product of the fast path inside i64 (offsets stay below 2^26
/// inside the guard band, the base below 2^61).
const NARROW_GRADIENT: u64 = 1 << 36;

/// Gradients below this keep a small triangle's planes inside i64 once they are on its pixel
/// grid (`AttrPlane::on_grid`), where they are only ever evaluated inside its rectangle.
///
/// Bounds: a small triangle's rectangle starts at the pixel column of its leftmost vertex (or
/// right of it, cut by the scissor) and at its first row whose centre lies between its top and
/// bottom vertex, and its vertices lie within 17 pixel columns and rows (`SMALL_EDGE`), so the
/// offset from the origin vertex to the centre of the rectangle's first pixel is below
/// `17 * 256 + 128 < 2^13` sub-pixels on each axis. Then `dx * ox + dy * oy + 128` stays below
/// `2 * 2^49 * 2^13 = 2^63`, and the base moves by less than 2^55 (after the shift by 8). Inside
/// the rectangle (at most 16 pixels a side) `dx * col + dy * row` stays below `2^54`: with the
/// base below 2^61, every value and sum of the small loop and the row step stays below 2^62.
pub(super) const SMALL_NARROW_GRADIENT: u64 = 1 << 49;

/// The gradient below which a triangle's planes stay inside i64 on its pixel grid, from how far
/// its rectangle's pixel centres lie from its origin vertex (`reach`, in sub-pixels, below
/// `2^b`): at least `NARROW_GRADIENT` (which holds anywhere in the guard band), and `2^(61 - b)`
/// where that is more. Then `dx * ox + dy * oy + 128` in `on_grid` stays below `2^62`, the base
/// moves by less than 2^54, and inside the rectangle (`256 * col` and `256 * row` at most twice
/// the reach) `dx * col + dy * row` stays below 2^55: with the base below 2^61, every value and
/// sum of the row step stays below 2^62, as for a small triangle (`SMALL_NARROW_GRADIENT`). A
/// triangle of a few dozen pixels thus gets narrow texture planes under exact perspective, whose
/// gradients pass `NARROW_GRADIENT`, and its rows start in i64 instead of 128-bit products.
///
/// Out of line: only triangles beyond 16x16 pixels ask, and inlined it costs the small
/// triangles' set-up loop registers (docs/optimisation-notes.md).
#[inline(never)]
pub(super) fn reach_gradient(c: &Coverage) -> u64 {
    let origin = c.origin();
    let (first, last) = (c.corner(), [c.rect.x1 as i64 - 1, c.rect.y1 as i64 - 1]);
    let centre = |p: i64| p * SUBPIXEL_ONE + SUBPIXEL_HALF;
    let reach = (0..2)
        .map(|k| {
            let (a, b) = (centre(first[k]) - origin[k], centre(last[k]) - origin[k]);
            a.unsigned_abs().max(b.unsigned_abs())
        })
        .max()
        .unwrap_or(0);
    let bits = 64 - reach.leading_zeros();
    NARROW_GRADIENT.max(1 << (61 - bits.min(61)))
}

/// The offset (sub-pixels) from the origin vertex at `origin` to the centre of pixel
/// `corner`, the first pixel of the triangle's rectangle: where `AttrPlane::on_grid` moves a
/// plane's base.
#[inline(always)]
pub(super) fn grid_offset(origin: [i64; 2], corner: [i64; 2]) -> [i64; 2] {
    [0, 1].map(|k| corner[k] * SUBPIXEL_ONE + SUBPIXEL_HALF - origin[k])
}

impl AttrPlane {
    /// True when the plane's gradients are below `limit` (`NARROW_GRADIENT`, or
    /// `SMALL_NARROW_GRADIENT` for a small triangle's).
    #[inline]
    pub(super) fn narrow_below(&self, limit: u64) -> bool {
        (self.dx.unsigned_abs() | self.dy.unsigned_abs()) < limit
    }

    /// True when the plane's gradients are small enough for i64 evaluation anywhere in the
    /// guard band.
    #[inline]
    fn narrow(&self) -> bool {
        self.narrow_below(NARROW_GRADIENT)
    }

    /// Moves a narrow plane's base from the origin vertex to the centre of the first pixel of the
    /// triangle's rectangle, `offset` from it (`grid_offset`). At pixel `corner + (col, row)`
    /// the offset is `(256 col + ox, 256 row + oy)` with `(ox, oy)` the offset of the corner's
    /// centre, so the rounded product `(dx * off_x + dy * off_y + 128) >> 8` of `at` splits
    /// exactly into `dx * col + dy * row` plus the same expression at the corner: a row start
    /// then costs two multiplications and no rounding (`at_pixel`). The offsets stay small
    /// inside the rectangle, which is what lets a small triangle's planes be narrow up to
    /// `SMALL_NARROW_GRADIENT`.
    ///
    /// In wrapping arithmetic, exact for a narrow plane: set-up moves each plane as it is made,
    /// and takes the moves back (`off_grid`) where one of the triangle's planes is not narrow.
    #[inline(always)]
    pub(super) fn on_grid(self, offset: [i64; 2]) -> Self {
        Self {
            base: self.base.wrapping_add(self.grid_move(offset)),
            ..self
        }
    }

    /// The plane `on_grid` was given, from what it gave.
    #[inline(always)]
    pub(super) fn off_grid(self, offset: [i64; 2]) -> Self {
        Self {
            base: self.base.wrapping_sub(self.grid_move(offset)),
            ..self
        }
    }

    /// What `on_grid` adds to the base.
    #[inline(always)]
    fn grid_move(&self, [ox, oy]: [i64; 2]) -> i64 {
        let half = 1 << (SUBPIXEL_BITS - 1);
        let sum = self
            .dx
            .wrapping_mul(ox)
            .wrapping_add(self.dy.wrapping_mul(oy));
        sum.wrapping_add(half) >> SUBPIXEL_BITS
    }

    /// The plane with value `base` at the centre of its rectangle's first pixel (or at the
    /// origin vertex) and gradients `dx, dy`: for tests of what reads planes.
    #[cfg(test)]
    pub(crate) fn with(base: i64, dx: i64, dy: i64) -> Self {
        Self { base, dx, dy }
    }

    /// Value at the centre of pixel `(col, row)` of the triangle's rectangle (counted from its
    /// first pixel) of a plane `on_grid`, equal to `at` there.
    #[inline]
    pub(crate) fn at_pixel(&self, col: i64, row: i64) -> i64 {
        self.base + self.dx * col + self.dy * row
    }

    /// Value at the sub-pixel offset `(ox, oy)` from the origin vertex.
    #[inline]
    pub(crate) fn at(&self, ox: i64, oy: i64) -> i64 {
        // Offsets stay below 2^26 inside the guard band, so gradients below 2^36 keep both
        // products and their sum inside i64, and the base (below 2^61) cannot overflow either:
        // the common case needs no 128-bit arithmetic. Same rounding as the wide path.
        if self.narrow() {
            let half = 1 << (SUBPIXEL_BITS - 1);
            return self.base + ((self.dx * ox + self.dy * oy + half) >> SUBPIXEL_BITS);
        }
        let d = self.dx as i128 * ox as i128 + self.dy as i128 * oy as i128;
        saturate_i64(self.base as i128 + shift_round(d, SUBPIXEL_BITS as i32))
    }
}

/// Per-triangle reciprocal of the doubled area, and the edge vectors from vertex 0.
///
/// Kept as i64 (edge vectors below 2^26, the reciprocal below 2^33) and widened per product, so
/// that every product of two of them is one widening multiplication.
pub(super) struct Geometry {
    d1: [i64; 2],
    d2: [i64; 2],
    inv_area: i64,
    shift: i32,
    /// Half of `2^shift`, the rounding of `plane_small`'s products (once per triangle, not per
    /// plane); 0 for a triangle that is not small.
    half: i64,
    /// Edge vectors below `SMALL_EDGE` (a small triangle): the planes take `plane_small`.
    small: bool,
    /// Numerators of one word whose magnitudes lie below this give a small triangle's plane
    /// gradients of at most 2^48, below `SMALL_NARROW_GRADIENT`: with `|n| < 2^(s + 16)` and
    /// `inv <= 2^32` the product lies within `2^(s + 48)`, and so the rounded quotient within
    /// `2^48`. Two tests of words instead of two of 64-bit values per plane.
    words_narrow: u32,
}

/// A plane as `Geometry` makes it, and whether its gradients are known to lie below
/// `SMALL_NARROW_GRADIENT` from their numerators (`Geometry::words_narrow`; false where
/// unknown, not where they do not).
pub(super) struct Made {
    pub plane: AttrPlane,
    pub narrow: bool,
}

/// Edge vectors of a triangle within 16x16 pixels (`Coverage::is_small`) stay below this many
/// sub-pixels: its extreme vertices lie in 17 pixel columns and rows, `|d| < 17 * 256 = 4352`.
///
/// With them, a plane needs no 128-bit sum (see `Geometry::plane_small`): attribute differences
/// stay below 2^45 (`s, t` under perspective: 2^24 texture units times `q < 2^20`, doubled),
/// so `nx = a1 * d2y - a2 * d1y` stays below 2 * 2^45 * 2^13 = 2^59; the doubled area below
/// `4352^2 < 2^25`, so it is shifted up by at least 6 to normalise it, and the plane's shift lies
/// in 8..=32.
const SMALL_EDGE: i64 = 1 << 13;

impl Geometry {
    /// The geometry of `v` (`small`: within 16x16 pixels, `Coverage::is_small`).
    pub(super) fn new(v: &[&FixedScreen; 3], area2: i64, small: bool) -> Self {
        let d = |i: usize| [v[i].xy[0] - v[0].xy[0], v[i].xy[1] - v[0].xy[1]];
        let (d1, d2) = (d(1), d(2));
        debug_assert!(!small || d1.iter().chain(&d2).all(|c| c.abs() < SMALL_EDGE));
        let (an, ash) = if small {
            // `normalise_positive` without 128-bit shifts: the area is below 2^25.
            debug_assert!(area2 > 0 && area2 < 1 << 25);
            let up = (area2 as u64).leading_zeros() as i32 - 33;
            (area2 << up, -up)
        } else {
            normalise_positive(area2 as i128)
        };
        // gradient per pixel, with ATTR_FRAC_BITS = num * 2^(SUBPIXEL_BITS + ATTR_FRAC_BITS) / area2
        let shift = 62 - (SUBPIXEL_BITS + ATTR_FRAC_BITS) as i32 + ash;
        Self {
            d1,
            d2,
            inv_area: reciprocal(an),
            shift,
            // The shift lies in 8..=32 for a small triangle (see `SMALL_EDGE`).
            half: if small { 1 << ((shift - 1) & 63) } else { 0 },
            small,
            words_narrow: 1u32.checked_shl((shift + 16) as u32).unwrap_or(u32::MAX),
        }
    }

    /// The plane of an attribute with values `a` at the vertices.
    #[inline(always)]
    pub(super) fn plane(&self, a: [i64; 3]) -> Made {
        self.plane_of::<false>(a)
    }

    /// `plane` of an attribute whose values lie in `0..=256` (colour, fog): a small triangle's
    /// numerators then fit in a word with no check (see `plane_small`).
    #[inline(always)]
    pub(super) fn plane_of_share(&self, a: [i64; 3]) -> Made {
        debug_assert!(a.iter().all(|v| (0..=256).contains(v)));
        self.plane_of::<true>(a)
    }

    #[inline(always)]
    fn plane_of<const SHARE: bool>(&self, a: [i64; 3]) -> Made {
        let (dx, dy, narrow) = if self.small {
            self.plane_small::<SHARE>(a)
        } else {
            let (dx, dy) = self.plane_wide(a);
            (dx, dy, false)
        };
        let plane = AttrPlane {
            base: a[0] << ATTR_FRAC_BITS,
            dx,
            dy,
        };
        Made { plane, narrow }
    }

    /// The gradients of a small triangle's plane: the products of `plane_wide` in i64, the
    /// scaled ones as one widening multiplication each (see `SMALL_EDGE` for the bounds). The
    /// same integers as `plane_wide`, so the same pixels.
    ///
    /// Where both differences lie within `2^17` (`SHARE`: values in `0..=256`, so within 2^9),
    /// the numerators are products of words: `|nx| < 2 * 2^17 * 2^13 = 2^31` (see `SMALL_EDGE`),
    /// and each gradient is `scale_word`'s one product, on every core (fewer instructions than
    /// the 128-bit product on a 64-bit one, and a few where a 32-bit one builds i64 products).
    /// Those numerators also tell whether the gradients are narrow (`words_narrow`, the third
    /// value; false for the others).
    #[inline(always)]
    fn plane_small<const SHARE: bool>(&self, a: [i64; 3]) -> (i64, i64, bool) {
        let (a1, a2) = (a[1] - a[0], a[2] - a[0]);
        debug_assert!(a1.abs() < 1 << 46 && a2.abs() < 1 << 46);
        debug_assert!((8..=32).contains(&self.shift));
        let s = self.shift as u32 & 63;
        let within = |a: i64| ((a + (1 << 17)) as u64) < 1 << 18;
        if SHARE || (within(a1) && within(a2)) {
            let [d1x, d1y, d2x, d2y] = [self.d1[0], self.d1[1], self.d2[0], self.d2[1]];
            let [a1, a2, d1x, d1y, d2x, d2y] = [a1, a2, d1x, d1y, d2x, d2y].map(|v| v as i32);
            return self.scaled_words(a1 * d2y - a2 * d1y, a2 * d1x - a1 * d2x, s);
        }
        let nx = a1 * self.d2[1] - a2 * self.d1[1];
        let ny = a2 * self.d1[0] - a1 * self.d2[0];
        // A 32-bit core takes numerators of one word as the words' path does (those of most
        // texture coordinates and depths).
        #[cfg(not(target_pointer_width = "64"))]
        if let (Ok(nx), Ok(ny)) = (i32::try_from(nx), i32::try_from(ny)) {
            return self.scaled_words(nx, ny, s);
        }
        // The shift masked: the compiler then knows it is below 64; the rounding half is below
        // 2^63, a 64-bit value added to the 128-bit product.
        let half = self.half as i128;
        let inv = self.inv_area as i128;
        let wide = |n: i64| i64::try_from((n as i128 * inv + half) >> s).ok();
        // A 32-bit core builds the 128-bit product from many words: there the gradients come
        // from 32x32-bit products where they lie below 2^62 (all but the steepest).
        #[cfg(not(target_pointer_width = "64"))]
        let wide = |n: i64| match i32::try_from(n) {
            Ok(n) => Some(scale_word(n, self.inv_area, self.half, s)),
            Err(_) => scale_in_words(n, self.inv_area, s).or_else(|| wide(n)),
        };
        match (wide(nx), wide(ny)) {
            (Some(dx), Some(dy)) => (dx, dy, false),
            _ => (0, 0, false),
        }
    }

    /// `plane_small`'s gradients from numerators of one word, and whether they are known narrow
    /// (`words_narrow`).
    #[inline(always)]
    fn scaled_words(&self, nx: i32, ny: i32, s: u32) -> (i64, i64, bool) {
        let scale = |n: i32| scale_word(n, self.inv_area, self.half, s);
        let narrow = (nx.unsigned_abs() | ny.unsigned_abs()) < self.words_narrow;
        (scale(nx), scale(ny), narrow)
    }

    /// The gradients of a plane, in 128-bit products.
    fn plane_wide(&self, a: [i64; 3]) -> (i64, i64) {
        let wide = |x: i64, y: i64| x as i128 * y as i128;
        // Attribute differences stay below 2^62 (depth 2^32, s and t 2^44, colour 2^8).
        let (a1, a2) = (a[1] - a[0], a[2] - a[0]);
        let nx = wide(a1, self.d2[1]) - wide(a2, self.d1[1]);
        let ny = wide(a2, self.d1[0]) - wide(a1, self.d2[0]);
        let inv = self.inv_area as i128;
        let (dx, dy) = (
            shift_round(nx * inv, self.shift),
            shift_round(ny * inv, self.shift),
        );
        match (i64::try_from(dx), i64::try_from(dy)) {
            (Ok(dx), Ok(dy)) => (dx, dy),
            // A gradient beyond i64 means the triangle is thinner than 2^-15 pixel across this
            // attribute's range: it can own at most isolated pixels, which take vertex 0's value.
            _ => (0, 0),
        }
    }
}

/// `(n * inv + half) >> s`, `plane_small`'s rounded product, for an `n` of one word (colour,
/// fog and the texture coordinates of most small triangles): with `inv <= 2^32` the product
/// lies within `2^63 - 2^32`, so it and the rounding half (below 2^31) stay in i64, and so does
/// the result. Three multiplications where the word's sign is known, against `scale_in_words`'
/// checks and shifts of two words.
#[inline(always)]
fn scale_word(n: i32, inv: i64, half: i64, s: u32) -> i64 {
    debug_assert!((1 << 31) < inv && inv <= 1 << 32 && (8..=32).contains(&s));
    debug_assert!(half == 1 << (s - 1));
    (n as i64 * inv + half) >> s
}

/// `(n * inv + 2^(s - 1)) >> s`, `plane_small`'s rounded product, in 32x32-bit products, for
/// `|n| < 2^60`, `inv` in `(2^31, 2^32]` (`Geometry::inv_area`) and `s` in `8..=32`, where the
/// result lies within `2^62` (`None` otherwise).
///
/// With `inv = 2^32 - c` (`c < 2^31`) and `n = 2^32 hi + lo` (`lo` its low word, unsigned),
/// `n inv + 2^(s - 1) = 2^32 h + l` with `h = n - hi c` and `l = 2^(s - 1) - lo c`: two products
/// of words (`hi c` below 2^59, `lo c` below 2^63), `|h| < 2^61`. As `s <= 32`, `2^s` divides
/// `2^32 h`, so the shifted sum is exactly `h 2^(32 - s) + (l >> s)`; where `|h| < 2^(30 + s)`
/// the first term lies within 2^62 and the second below 2^55, so neither the terms nor the sum
/// leave i64.
#[cfg(any(test, not(target_pointer_width = "64")))]
#[inline(always)]
fn scale_in_words(n: i64, inv: i64, s: u32) -> Option<i64> {
    debug_assert!(n.unsigned_abs() < 1 << 60 && (1 << 31) < inv && inv <= 1 << 32);
    debug_assert!((8..=32).contains(&s));
    let c = ((1i64 << 32) - inv) as i32;
    let (hi, lo) = ((n >> 32) as i32, n as u32);
    let h = n - hi as i64 * c as i64;
    let l = (1i64 << (s - 1)) - (lo as u64 * c as u64) as i64;
    // `|h| < 2^(30 + s)` read off its high word (`2^32` divides `2^(30 + s)`).
    let top = (h >> 32) as i32;
    // Shifts by less than 32 (masked so that the compiler knows it): a few instructions on
    // a 32-bit core, where a shift by any amount below 64 takes a dozen.
    let within = (top.wrapping_add(1 << ((s - 2) & 31)) as u32) < 1 << ((s - 1) & 31);
    within.then(|| (h << ((32 - s) & 31)) + ((l >> 1) >> ((s - 1) & 31)))
}

#[cfg(test)]
mod tests {
    use super::super::test_support::{EDGE, SCREEN};
    use super::*;
    use crate::edge::PixelRect;
    use crate::fixed_point::{GUARD_BAND_PX, MAX_DIMENSION};

    /// The geometry `Geometry::new` makes of the triangle `v` (sub-pixels), if its orientation
    /// is positive.
    fn geometry(v: [[i64; 2]; 3], small: bool) -> Option<Geometry> {
        let d = |i: usize| [v[i][0] - v[0][0], v[i][1] - v[0][1]];
        let area2 = d(1)[0] * d(2)[1] - d(2)[0] * d(1)[1];
        let screen = v.map(|xy| FixedScreen {
            xy,
            ..FixedScreen::default()
        });
        (area2 > 0).then(|| Geometry::new(&[&screen[0], &screen[1], &screen[2]], area2, small))
    }

    /// The largest attribute difference a plane meets: `s, t` under perspective.
    const MAX_ATTR: i64 = 1 << 45;
    /// Reciprocals of areas (`Geometry::inv_area`, in `(2^31, 2^32]`): the ends and between.
    const RECIPROCALS: [i64; 5] = [
        (1 << 31) + 1,
        (1 << 31) + 12345,
        3 << 30,
        (1 << 32) - 1,
        1 << 32,
    ];

    /// `scale_word` against the 128-bit product.
    fn check_word(n: i32, inv: i64, s: u32) {
        let wide = (n as i128 * inv as i128 + (1i128 << (s - 1))) >> s;
        assert_eq!(
            scale_word(n, inv, 1 << (s - 1), s) as i128,
            wide,
            "{n} {inv} {s}"
        );
    }

    #[test]
    fn products_of_a_word_equal_128_bit_products_at_the_bounds() {
        for s in 8..=32 {
            for n in [
                0,
                1,
                -1,
                12345,
                -12345,
                i32::MAX,
                i32::MIN,
                i32::MAX - 1,
                i32::MIN + 1,
            ] {
                for inv in RECIPROCALS {
                    check_word(n, inv, s);
                }
            }
        }
    }

    /// `scale_in_words` against the 128-bit product, where it gives a value.
    fn check_scale(n: i64, inv: i64, s: u32) -> bool {
        let wide = i64::try_from((n as i128 * inv as i128 + (1i128 << (s - 1))) >> s).ok();
        let words = scale_in_words(n, inv, s);
        if words.is_some() {
            assert_eq!(words, wide, "{n} {inv} {s}");
        }
        words.is_some()
    }

    #[test]
    fn products_in_words_equal_128_bit_products_at_the_bounds() {
        let (mut given, mut all) = (0, 0);
        let top = (1i64 << 60) - 1;
        for s in 8..=32 {
            // Around the words' bound on `h` (about `n`), and the ends.
            let bound = 1i64 << (30 + s);
            let ns = [
                0,
                1,
                2,
                (1 << 31) - 1,
                1 << 31,
                1 << 32,
                bound - 1,
                bound,
                bound + 1,
                top,
            ];
            for n in ns.iter().flat_map(|&n| [n.min(top), -n.min(top)]) {
                for inv in RECIPROCALS {
                    given += check_scale(n, inv, s) as u32;
                    all += 1;
                }
            }
        }
        assert!(given * 4 > all * 3 && given < all, "{given} of {all}");
    }

    proptest::proptest! {
        #[test]
        fn products_in_words_equal_128_bit_products(
            n in -(1i64 << 60) + 1..1 << 60,
            inv in (1i64 << 31) + 1..=1 << 32,
            s in 8u32..=32,
            bits in 0u32..61,
        ) {
            check_scale(n, inv, s);
            check_scale(n >> bits, inv, s);
            check_word((n >> 29) as i32, inv, s);
        }
    }

    #[test]
    fn small_planes_equal_wide_planes_at_the_bounds() {
        let at = [0, 1, EDGE / 3, EDGE / 2 + 7, EDGE - 1, EDGE];
        let points: Vec<[i64; 2]> = at.iter().flat_map(|&x| at.map(|y| [x, y])).collect();
        // The ends of every range, and of the words' (`plane_small`).
        let word = 1 << 17;
        let attrs = [
            -MAX_ATTR,
            -(1 << 32),
            -word - 1,
            -word,
            -255,
            0,
            1,
            word - 1,
            word,
            1 << 24,
            MAX_ATTR,
        ];
        let shares = [0, 1, 255, 256];
        let (mut checked, mut largest, mut narrow) = (0, 0, [0; 2]);
        for &a in &points {
            for &b in &points {
                for &c in &points {
                    let (Some(small), Some(wide)) =
                        (geometry([a, b, c], true), geometry([a, b, c], false))
                    else {
                        continue;
                    };
                    assert_eq!((small.inv_area, small.shift), (wide.inv_area, wide.shift));
                    largest = largest.max(small.shift);
                    for a1 in attrs {
                        for a2 in attrs {
                            let q = [0, a1, a2];
                            let (gradients, known) = small_gradients::<false>(&small, q);
                            assert_eq!(gradients, wide.plane_wide(q));
                            checked += 1;
                            narrow[known as usize] += 1;
                        }
                    }
                    for a0 in shares {
                        for a1 in shares {
                            for a2 in shares {
                                let q = [a0, a1, a2];
                                let (gradients, _) = small_gradients::<true>(&small, q);
                                assert_eq!(gradients, wide.plane_wide(q));
                            }
                        }
                    }
                }
            }
        }
        // The largest area (a right angle on the box's corners) has the largest shift.
        assert_eq!(largest, 32);
        assert!(checked > 100_000, "{checked} planes");
        // Words' numerators tell narrow gradients for many planes, not all.
        assert!(narrow.iter().all(|&n| n > checked / 10), "{narrow:?}");
    }

    /// `plane_small`'s gradients, and whether it knew them narrow, which they then are.
    fn small_gradients<const SHARE: bool>(g: &Geometry, a: [i64; 3]) -> ((i64, i64), bool) {
        let (dx, dy, narrow) = g.plane_small::<SHARE>(a);
        if narrow {
            let plane = AttrPlane { base: 0, dx, dy };
            assert!(plane.narrow_below(SMALL_NARROW_GRADIENT), "{a:?} {dx} {dy}");
            assert!(
                dx.unsigned_abs().max(dy.unsigned_abs()) <= 1 << 48,
                "{a:?} {dx} {dy}"
            );
        }
        ((dx, dy), narrow)
    }

    proptest::proptest! {
        /// The small triangles' planes (i64 products) are the integers of the 128-bit ones.
        #[test]
        fn small_planes_equal_wide_planes(
            v in proptest::collection::vec(0..=EDGE, 6),
            a in proptest::collection::vec(-MAX_ATTR / 2..=MAX_ATTR / 2, 3),
            bits in 0u32..46,
            shares in proptest::collection::vec(0i64..=256, 3),
        ) {
            let v = [[v[0], v[1]], [v[2], v[3]], [v[4], v[5]]];
            if let (Some(small), Some(wide)) = (geometry(v, true), geometry(v, false)) {
                // Values of every size, down to the words' (`plane_small`), and shares.
                let a = [a[0], a[1], a[2]].map(|a| a >> bits);
                proptest::prop_assert_eq!(small_gradients::<false>(&small, a).0, wide.plane_wide(a));
                let s = [shares[0], shares[1], shares[2]];
                proptest::prop_assert_eq!(small_gradients::<true>(&small, s).0, wide.plane_wide(s));
            }
        }
    }

    proptest::proptest! {
        /// Rows of narrow triangles start from the plane moved onto the pixel grid: it must give
        /// the very value `at` gives from the origin vertex, at every pixel centre.
        #[test]
        fn a_plane_on_the_pixel_grid_equals_the_plane_at_every_pixel(
            base in -(1i64 << 60)..1 << 60,
            dx in -(1i64 << 36) + 1..1 << 36,
            dy in -(1i64 << 36) + 1..1 << 36,
            origin in (-(1i64 << 23)..1 << 23, -(1i64 << 23)..1 << 23),
            corner in (0i64..4096, 0i64..4096),
            pixel in (0i64..4096, 0i64..4096),
        ) {
            let plane = AttrPlane { base, dx, dy };
            let origin = [origin.0, origin.1];
            let corner = [corner.0, corner.1];
            let (x, y) = (corner[0] + pixel.0, corner[1] + pixel.1);
            let ox = x * SUBPIXEL_ONE + SUBPIXEL_HALF - origin[0];
            let oy = y * SUBPIXEL_ONE + SUBPIXEL_HALF - origin[1];
            let on_grid = plane.on_grid(grid_offset(origin, corner));
            proptest::prop_assert_eq!(on_grid.at_pixel(pixel.0, pixel.1), plane.at(ox, oy));
        }

        /// A triangle whose planes are not all narrow takes their moves back: any plane, moved
        /// onto the grid and back, is the plane it was.
        #[test]
        fn a_plane_moved_onto_the_grid_and_back_is_the_plane_it_was(
            (base, dx, dy) in (proptest::num::i64::ANY, proptest::num::i64::ANY, proptest::num::i64::ANY),
            origin in (-(1i64 << 25)..1 << 25, -(1i64 << 25)..1 << 25),
            corner in (-(1i64 << 17)..1 << 17, -(1i64 << 17)..1 << 17),
        ) {
            let plane = AttrPlane { base, dx, dy };
            let offset = grid_offset([origin.0, origin.1], [corner.0, corner.1]);
            let back = plane.on_grid(offset).off_grid(offset);
            proptest::prop_assert_eq!((back.base, back.dx, back.dy), (base, dx, dy));
        }
    }

    /// The value of `plane` (based at the origin vertex) at the centre of pixel `(x, y)`, in
    /// 128-bit products: what the rows of a plane that is not narrow start from.
    fn at_in_128_bits(plane: &AttrPlane, origin: [i64; 2], x: i64, y: i64) -> i128 {
        let ox = (x * SUBPIXEL_ONE + SUBPIXEL_HALF - origin[0]) as i128;
        let oy = (y * SUBPIXEL_ONE + SUBPIXEL_HALF - origin[1]) as i128;
        plane.base as i128 + shift_round(plane.dx as i128 * ox + plane.dy as i128 * oy, 8)
    }

    /// Checks a small triangle's plane on its pixel grid against the 128-bit evaluation at every
    /// pixel of its rectangle (with overflow checks on, an overflow on the way panics). Returns
    /// false when `v` is not a small triangle owning a row inside `clip`.
    fn check_small_plane(v: [[i64; 2]; 3], plane: AttrPlane, clip: PixelRect) -> bool {
        let Some((origin, cov)) = covered(v, clip).filter(|(_, c)| c.is_small()) else {
            return false;
        };
        assert!(plane.narrow_below(SMALL_NARROW_GRADIENT));
        let r = cov.rect;
        let pixels = (r.y0 as i64..r.y1 as i64)
            .flat_map(|y| (r.x0 as i64..r.x1 as i64).map(move |x| (x, y)));
        assert_on_grid(plane, origin, &cov, pixels);
        true
    }

    /// The origin vertex of `v` in positive orientation and its coverage inside `clip`, when it
    /// has an area and owns a row there.
    fn covered(v: [[i64; 2]; 3], clip: PixelRect) -> Option<([i64; 2], Coverage)> {
        let d = |i: usize| [v[i][0] - v[0][0], v[i][1] - v[0][1]];
        let area2 = d(1)[0] * d(2)[1] - d(2)[0] * d(1)[1];
        let v = if area2 < 0 { [v[0], v[2], v[1]] } else { v };
        Coverage::new(v, clip)
            .filter(|_| area2 != 0)
            .map(|c| (v[0], c))
    }

    /// Asserts that `plane` (based at `origin`) moved onto the pixel grid of `cov` gives the
    /// 128-bit value at each of `pixels`, and that the value stays below 2^62.
    fn assert_on_grid(
        plane: AttrPlane,
        origin: [i64; 2],
        cov: &Coverage,
        pixels: impl IntoIterator<Item = (i64, i64)>,
    ) {
        let corner = cov.corner();
        let on_grid = plane.on_grid(grid_offset(origin, corner));
        for (x, y) in pixels {
            let got = on_grid.at_pixel(x - corner[0], y - corner[1]);
            let wide = at_in_128_bits(&plane, origin, x, y);
            assert!(
                wide.unsigned_abs() < 1 << 62,
                "{origin:?} {plane:?} ({x}, {y})"
            );
            assert_eq!(got as i128, wide, "{origin:?} {plane:?} ({x}, {y})");
        }
    }

    #[test]
    fn small_planes_on_the_pixel_grid_equal_128_bit_products_at_the_extremes() {
        let cut = PixelRect {
            x0: 7,
            y0: 7,
            x1: 9,
            y1: 9,
        };
        let g = SMALL_NARROW_GRADIENT as i64 - 1;
        let gradients = [-g, -(1 << 36), -1, 0, 1, g];
        let bases = [-(1i64 << 60), 0, (1 << 60) - 1];
        // Vertices at the far ends of the 16 pixel columns and rows a small triangle's vertices
        // lie in (at either side of a pixel), with the origin vertex at either end.
        let (mut checked, mut at) = (0, 0);
        for (lo, hi) in [
            (0, 15 * SUBPIXEL_ONE),
            (SUBPIXEL_ONE - 1, 16 * SUBPIXEL_ONE - 1),
        ] {
            let shapes = [
                [[lo, lo], [hi, lo], [lo, hi]],
                [[hi, hi], [lo, hi], [hi, lo]],
                [[hi, lo], [lo, hi], [hi, hi]],
                [[lo, hi], [hi, hi], [lo, lo]],
                [[lo, lo], [hi, hi], [lo + 1, hi]],
            ];
            for shape in shapes {
                for clip in [SCREEN, cut] {
                    for dx in gradients {
                        for dy in gradients {
                            for base in bases {
                                let plane = AttrPlane { base, dx, dy };
                                at += 1;
                                checked += check_small_plane(shape, plane, clip) as u32;
                            }
                        }
                    }
                }
            }
        }
        assert!(checked * 4 > at, "{checked} of {at}");
    }

    proptest::proptest! {
        /// A small triangle anywhere in the guard band, with gradients up to the small bound: its
        /// planes on its pixel grid give the 128-bit values at every pixel of its rectangle.
        #[test]
        fn small_planes_on_the_pixel_grid_equal_128_bit_products(
            at in (-(1i64 << 23)..1 << 23, -(1i64 << 23)..1 << 23),
            v in proptest::collection::vec(0..16 * SUBPIXEL_ONE, 6),
            base in -(1i64 << 60)..1 << 60,
            dx in -(SMALL_NARROW_GRADIENT as i64) + 1..SMALL_NARROW_GRADIENT as i64,
            dy in -(SMALL_NARROW_GRADIENT as i64) + 1..SMALL_NARROW_GRADIENT as i64,
            clip in (0i32..8192, 0i32..8192, 1i32..8192, 1i32..8192),
        ) {
            // Some triangles on screen, inside the scissor; the others wherever `at` puts them.
            let near = (at.0 & 1) == 0;
            let origin = if near {
                [(clip.0 as i64 - 4) * SUBPIXEL_ONE, (clip.1 as i64 - 4) * SUBPIXEL_ONE]
            } else {
                [at.0, at.1]
            };
            let v = [0, 1, 2].map(|i| [origin[0] + v[2 * i], origin[1] + v[2 * i + 1]]);
            let clip = PixelRect {
                x0: clip.0,
                y0: clip.1,
                x1: (clip.0 + clip.2).min(MAX_DIMENSION as i32),
                y1: (clip.1 + clip.3).min(MAX_DIMENSION as i32),
            };
            check_small_plane(v, AttrPlane { base, dx, dy }, clip);
        }
    }

    /// Checks a triangle's plane with gradients at its reach bound (`reach_gradient`) on its
    /// pixel grid against the 128-bit evaluation at the corners of its rectangle, where an affine
    /// function is extreme (with overflow checks on, an overflow on the way panics). Returns false
    /// when `v` owns no row inside `clip` or is small (`SMALL_NARROW_GRADIENT` covers those).
    fn check_reach_plane(v: [[i64; 2]; 3], base: i64, signs: [i64; 2], clip: PixelRect) -> bool {
        let Some((origin, cov)) = covered(v, clip).filter(|(_, c)| !c.is_small()) else {
            return false;
        };
        let g = reach_gradient(&cov) as i64 - 1;
        let plane = AttrPlane {
            base,
            dx: signs[0] * g,
            dy: signs[1] * g,
        };
        assert!(plane.narrow_below(reach_gradient(&cov)));
        let r = cov.rect;
        let (xs, ys) = ([r.x0, r.x1 - 1], [r.y0, r.y1 - 1]);
        let corners = ys
            .into_iter()
            .flat_map(|y| xs.map(|x| (x as i64, y as i64)));
        assert_on_grid(plane, origin, &cov, corners);
        true
    }

    #[test]
    fn planes_at_their_reach_bound_equal_128_bit_products_at_the_extremes() {
        let cut = PixelRect {
            x0: 100,
            y0: 100,
            x1: 140,
            y1: 120,
        };
        let band = GUARD_BAND_PX * SUBPIXEL_ONE;
        let (far, edge) = (MAX_DIMENSION as i64 * SUBPIXEL_ONE + band - 1, -band);
        let (mut checked, mut at) = (0, 0);
        // From a 17-pixel triangle to one across the whole guard band, with the origin vertex at
        // either end, on screen and cut by a scissor.
        for size in [
            17 * SUBPIXEL_ONE,
            40 * SUBPIXEL_ONE,
            1 << 16,
            1 << 20,
            far - edge,
        ] {
            for (lo, hi) in [(0, size), (edge, edge + size), (far - size, far)] {
                let shapes = [
                    [[lo, lo], [hi, lo], [lo, hi]],
                    [[hi, hi], [lo, hi], [hi, lo]],
                    [[lo, lo], [hi, hi], [lo + 1, hi]],
                ];
                for shape in shapes {
                    for clip in [SCREEN, cut] {
                        for signs in [[1, 1], [1, -1], [-1, 1], [-1, -1]] {
                            for base in [-(1i64 << 61) + 1, 0, (1 << 61) - 1] {
                                at += 1;
                                checked += check_reach_plane(shape, base, signs, clip) as u32;
                            }
                        }
                    }
                }
            }
        }
        assert!(checked * 4 > at, "{checked} of {at}");
    }

    proptest::proptest! {
        /// A triangle of any size anywhere in the guard band, with gradients at its reach bound:
        /// its planes on its pixel grid give the 128-bit values at the corners of its rectangle.
        #[test]
        fn planes_at_their_reach_bound_equal_128_bit_products(
            v in proptest::collection::vec(-(1i64 << 23)..3 << 22, 6),
            base in -(1i64 << 61) + 1..1 << 61,
            signs in (proptest::bool::ANY, proptest::bool::ANY),
            clip in (0i32..8192, 0i32..8192, 1i32..8192, 1i32..8192),
        ) {
            let v = [0, 1, 2].map(|i| [v[2 * i], v[2 * i + 1]]);
            let sign = |b: bool| if b { 1 } else { -1 };
            let clip = PixelRect {
                x0: clip.0,
                y0: clip.1,
                x1: (clip.0 + clip.2).min(MAX_DIMENSION as i32),
                y1: (clip.1 + clip.3).min(MAX_DIMENSION as i32),
            };
            check_reach_plane(v, base, [sign(signs.0), sign(signs.1)], clip);
        }
    }
}
