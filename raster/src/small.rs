//! Small triangles in one loop: the coverage walk, the cut to the tile and the row step of a
//! triangle within 16x16 pixels whose attribute planes give every pixel on its own.
//!
//! Terrain triangles own a few pixels in each of a few rows (on the handheld frame 8 pixels in
//! 3 rows on average), so what a row costs besides its pixels decides the frame. Here a row is a
//! mask of owned columns from the edge functions in lanes (`SmallRows`), its run is the mask's
//! first and last bit, and every value at the run's start is its plane at that pixel (the base
//! plus two products, on the rows that own pixels only). The pixels go to the fragment buffer by
//! index, and its colour stage writes them by index into the tile.
//!
//! The values are those of the general row step: a narrow plane at a pixel is exact wherever it
//! is evaluated from (see `AttrPlane::on_grid`), and neither sums nor products of it overflow.
//! When the triangle's vertices hold values far enough inside the ranges its pixel values are
//! clamped to (`FixedTriangle::bounded`, decided once at set-up), the clamps are left out;
//! under perspective, so are the division's when the texture planes bound every quotient over
//! the rows and columns the triangle can own here (an affine function over a rectangle is
//! extreme at its corners).

use crate::edge::PixelRect;
use crate::fixed_point::{ATTR_FRAC_BITS, TEXCOORD_LIMIT};
use crate::fragments::Fragments;
use crate::pipeline::TexMode;
use crate::pipeline::fixed::{
    AttrPlane, DepthTest, FixedTriangle, NarrowPlanes, WORDS, divide, divide_in_range,
    plane_offsets,
};
use crate::pixel::DepthStorage;
use crate::sampler::{Filtering, clamp_coord};
use crate::tile_view::TileBuf;

/// Draws the rows of `t` (small and narrow, with planes `p` that are `NarrowPlanes::per_pixel`)
/// inside `tile` (and its `depth`) into `frags`, coloured by `flush` whenever the buffer fills.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(crate) fn small_triangle<
    D: DepthStorage,
    F: Filtering,
    const SHADE: bool,
    const GREY: bool,
    const FOG: bool,
>(
    p: &NarrowPlanes,
    t: &FixedTriangle,
    tile: PixelRect,
    depth: Option<&mut TileBuf<'_, D::Value>>,
    frags: &mut Fragments,
    flush: &mut dyn FnMut(&mut Fragments),
    test: DepthTest,
) {
    let rect = t.coverage.rect;
    // The rows `small_rows` walks: built in `rows_of`, where they live.
    let (y0, end) = (rect.y0.max(tile.y0) as i64, rect.y1.min(tile.y1) as i64);
    if y0 >= end {
        return;
    }
    // The texture's interpolation, fixed for the row loop: texture coordinates per pixel
    // (affine), the perspective accumulators (exact), or none.
    // A textured run's mode is never `Off` (`Attributes::tex_mode_for`).
    let texes = match p.tex_mode {
        _ if !F::ENABLED => TEX_OFF,
        TexMode::Perspective(_) => TEX_PERSPECTIVE,
        _ => TEX_AFFINE,
    };
    debug_assert!(!F::ENABLED || p.tex_mode != TexMode::Off);
    let mut in_range = t.bounded
        && (texes != TEX_PERSPECTIVE || {
            // The perspective planes at the first row here, and the last column and row the
            // triangle may own, from there.
            let start = p.tex.map(|q| q.at_pixel(0, y0 - rect.y0 as i64));
            let (w, h) = ((rect.x1 - rect.x0 - 1) as i64, end - y0 - 1);
            quotients_in_range(&p.tex, &start, w, h)
        });
    // Where runs step texture coordinates in words, the offsets of their words, over the
    // rectangle's columns and its rows down to the last drawn here; the i64 steps where they
    // spread too far.
    let mut offsets = [0; 2];
    if WORDS && in_range && texes == TEX_AFFINE {
        let (w, h) = ((rect.x1 - rect.x0 - 1) as i64, end - rect.y0 as i64 - 1);
        match word_offsets(&p.tex, w, h) {
            Some(o) => offsets = o,
            None => in_range = false,
        }
    }
    // The branch on the constant `F::ENABLED` keeps the compiler from building the textured row
    // loops for untextured runs and the untextured one for textured runs, which no draw can
    // reach.
    if !F::ENABLED {
        return match in_range {
            false => rows_of::<D, SHADE, GREY, FOG, TEX_OFF, true>(
                p, t, offsets, tile, depth, frags, flush, test,
            ),
            true => rows_of::<D, SHADE, GREY, FOG, TEX_OFF, false>(
                p, t, offsets, tile, depth, frags, flush, test,
            ),
        };
    }
    match (texes, in_range) {
        (TEX_PERSPECTIVE, false) => rows_of::<D, SHADE, GREY, FOG, TEX_PERSPECTIVE, true>(
            p, t, offsets, tile, depth, frags, flush, test,
        ),
        (TEX_PERSPECTIVE, true) => rows_of::<D, SHADE, GREY, FOG, TEX_PERSPECTIVE, false>(
            p, t, offsets, tile, depth, frags, flush, test,
        ),
        (_, false) => rows_of::<D, SHADE, GREY, FOG, TEX_AFFINE, true>(
            p, t, offsets, tile, depth, frags, flush, test,
        ),
        (_, true) => rows_of::<D, SHADE, GREY, FOG, TEX_AFFINE, false>(
            p, t, offsets, tile, depth, frags, flush, test,
        ),
    }
}

/// True when `divide`'s quotients need no clamp at any pixel `(col, row)`, `col <= w`,
/// `row <= h`, of the perspective planes `tex` (`s, t, q`, with values `start` at `(0, 0)`):
/// they do not where `q >= 2` and `|s|, |t| <= q * TEXCOORD_LIMIT` (see `divide_in_range`). With
/// `q` at least its least value `q0 >= 2` over the rectangle (an affine function is extreme at
/// its corners), `s` and `t` within `q0 * TEXCOORD_LIMIT` suffice; `q0` is capped so that the
/// product stays in i64 (a smaller bound only sends more triangles to the clamps).
fn quotients_in_range(tex: &[AttrPlane; 3], start: &[i64; 3], w: i64, h: i64) -> bool {
    let q0 = extremes(&tex[2], start[2], w, h).0.min(1 << 37);
    q0 >= 2 && {
        let bound = q0 * TEXCOORD_LIMIT;
        (0..2).all(|k| {
            let (lo, hi) = extremes(&tex[k], start[k], w, h);
            lo >= -bound && hi <= bound
        })
    }
}

/// The least and the greatest value of plane `q` over the pixels `(col, row)`, `col <= w`,
/// `row <= h`, where its value at `(0, 0)` is `v`: an affine function over a rectangle is
/// extreme at its corners.
#[inline(always)]
fn extremes(q: &AttrPlane, v: i64, w: i64, h: i64) -> (i64, i64) {
    let (ex, ey) = (q.dx * w, q.dy * h);
    (v + ex.min(0) + ey.min(0), v + ex.max(0) + ey.max(0))
}

/// The row loop's texture interpolation, as the number of texture planes it steps: none,
/// `u, v` (affine) or `s, t, q` (perspective, a division per pixel).
const TEX_OFF: usize = 0;
const TEX_AFFINE: usize = 2;
const TEX_PERSPECTIVE: usize = 3;

/// Values a run steps in words: none where runs take no words.
const WORD_VALUES: usize = if WORDS { VALUES } else { 0 };

/// Values a run steps at most: depth, three colour channels, fog, three perspective planes.
const VALUES: usize = 8;

/// Offsets that put the affine texture planes `tex` (`u, v`) in 32-bit words at every pixel
/// `(col, row)`, `col <= w`, `row <= h`, of the rectangle: for each, its value at the first
/// pixel rounded down to a multiple of `2^16`, where the plane strays from that value by less
/// than `2^31 - 2^16` over those pixels (by at most `|dx| w + |dy| h`); `None` where a plane
/// spreads further (about half a repeat of the texture).
///
/// At such a pixel the plane's value `c` lies within `2^31` of the offset `o` either way
/// (`-2^31 <= c - o < 2^31`), so the word `c - o` is exact in i32 wrapping arithmetic (which
/// computes every integer modulo 2^32), and, `o` being a multiple of `2^16`, `c >> 16` is
/// `((c - o) >> 16) + (o >> 16)` (an arithmetic shift rounds down whatever the sign): that sum
/// in wrapping i32 is exact too, as `c >> 16` itself lies within the texture-coordinate range
/// at a pixel a bounded triangle owns (`FixedTriangle::bounded`). No extremes are needed: the
/// first pixel's value and two products.
fn word_offsets(tex: &[AttrPlane; 3], w: i64, h: i64) -> Option<[i64; 2]> {
    let offset = |q: &AttrPlane| {
        let reach = (q.dx * w).unsigned_abs() + (q.dy * h).unsigned_abs();
        (reach < (1 << 31) - (1 << 16)).then_some(q.at_pixel(0, 0) & !((1 << 16) - 1))
    };
    Some([offset(&tex[0])?, offset(&tex[1])?])
}

/// A plane's value at pixel `(col, row)` minus `offset`, in i32 wrapping arithmetic: the
/// integer itself wherever it lies in i32 (see `word_offsets`).
#[inline(always)]
fn word_at(q: &AttrPlane, offset: i64, col: i32, row: i32) -> i32 {
    let base = q.at_pixel(0, 0).wrapping_sub(offset) as i32;
    base.wrapping_add((q.dx as i32).wrapping_mul(col))
        .wrapping_add((q.dy as i32).wrapping_mul(row))
}

/// The row loop of `small_triangle`: `TEX` texture planes (`TEX_OFF`, `TEX_AFFINE` or
/// `TEX_PERSPECTIVE`); `CLAMP` false when every value, and every quotient of the perspective
/// division, is known to be in range, and the affine texture planes' words are `offsets` from
/// their values (`word_offsets`).
///
/// Without clamps and perspective, colour, fog and texture coordinates step in 32-bit words:
/// at a pixel the triangle owns, a colour or fog value (16 fraction bits) lies in its range,
/// below 2^25, and i32 wrapping arithmetic, exact modulo 2^32, gives that integer itself
/// wherever the i64 steps would (texture coordinates: `word_offsets`); depth (0.32 with 16
/// fraction bits) stays in i64. On a 32-bit core that halves the adds and the registers a pixel
/// needs.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn rows_of<
    D: DepthStorage,
    const SHADE: bool,
    const GREY: bool,
    const FOG: bool,
    const TEX: usize,
    const CLAMP: bool,
>(
    p: &NarrowPlanes,
    t: &FixedTriangle,
    offsets: [i64; 2],
    tile: PixelRect,
    depth: Option<&mut TileBuf<'_, D::Value>>,
    frags: &mut Fragments,
    flush: &mut dyn FnMut(&mut Fragments),
    test: DepthTest,
) {
    let depth: &mut [D::Value] = match depth {
        Some(d) if D::ENABLED => d.pixels(),
        _ => &mut [],
    };
    // Colour, fog and texture coordinates in words (see above).
    let words = WORDS && !CLAMP && TEX != TEX_PERSPECTIVE;
    let mut rows = t.coverage.small_rows(tile.y0 as i64, tile.y1 as i64);
    // Where each kind of value sits among the run's stepped values: the planes' own order.
    let (color_at, fog_at, tex_at) = plane_offsets::<D, SHADE, GREY, FOG>();
    let channels = fog_at - color_at;
    // What the words of `u, v` add back: `o >> 16` (see `word_offsets`).
    let uv_offsets = if words {
        offsets.map(|o| (o >> 16) as i32)
    } else {
        [0; 2]
    };
    // The tile's columns as bits of the rows' masks (a small triangle spans at most 16).
    let lo = (tile.x0 as i64 - rows.x0).clamp(0, 32);
    let hi = (tile.x1 as i64 - rows.x0).clamp(0, 32);
    let inside_tile = ((1u64 << hi) - (1u64 << lo)) as u32;
    // Index in the tile's buffers of the current row's pixel at the rectangle's first column,
    // which may lie left of the tile (every run starts inside it).
    let width = (tile.x1 - tile.x0) as i64;
    let mut row_at = (rows.y - tile.y0 as i64) * width + (rows.x0 - tile.x0 as i64);
    // The planes' rows and columns count from the rectangle's first pixel (`rows.x0` is its
    // first column).
    let top = t.coverage.rect.y0 as i64;
    while rows.y < rows.end {
        let row = rows.y - top;
        let owned = rows.next_mask() & inside_tile;
        if owned != 0 {
            let first = owned.trailing_zeros() as usize;
            let n = (32 - owned.leading_zeros()) as usize - first;
            if n > frags.room() {
                flush(frags);
            }
            let at = (row_at + first as i64) as usize;
            let mut k = frags.held();
            let start = |q: &AttrPlane| q.at_pixel(first as i64, row);
            // Every value the run steps, in one array: depth, the colour channels, fog, the
            // texture's (or the perspective accumulators); in words, all but depth.
            let mut acc = [0i64; VALUES];
            let mut step = [0i64; VALUES];
            let mut word = [0i32; WORD_VALUES];
            let mut word_step = [0i32; WORD_VALUES];
            // `put(index, q, None)` for depth, `Some(offset)` for the values words may hold.
            let mut put = |index: usize, q: &AttrPlane, offset: Option<i64>| match offset {
                Some(offset) if words => {
                    word[index] = word_at(q, offset, first as i32, row as i32);
                    word_step[index] = q.dx as i32;
                }
                _ => {
                    acc[index] = start(q);
                    step[index] = q.dx;
                }
            };
            if D::ENABLED {
                put(0, &p.z, None);
            }
            for (ch, q) in p.c.iter().enumerate().take(channels) {
                put(color_at + ch, q, Some(0));
            }
            if FOG {
                put(fog_at, &p.f, Some(0));
            }
            for (plane, q) in p.tex.iter().enumerate().take(TEX) {
                put(
                    tex_at + plane,
                    q,
                    Some(offsets.get(plane).copied().unwrap_or(0)),
                );
            }
            // A value's integer part (its 16 fraction bits dropped), from its word or its i64.
            let whole = |acc: &[i64; VALUES], word: &[i32; WORD_VALUES], index: usize| {
                if words {
                    (word[index] >> ATTR_FRAC_BITS) as i64
                } else {
                    acc[index] >> ATTR_FRAC_BITS
                }
            };
            // The run's depth values, sliced once: indexed by `j < n`, they need no check per
            // pixel. A fragment takes its slot `k` only when it passes (`Fragments`).
            let depth_row: &mut [D::Value] = if D::ENABLED {
                &mut depth[at..at + n]
            } else {
                &mut []
            };
            // Indexed, not iterated: without a depth test `depth_row` is empty.
            #[allow(clippy::needless_range_loop)]
            for j in 0..n {
                let i = Fragments::slot(k);
                frags.at[i] = (at + j) as u32;
                let pass = if D::ENABLED {
                    let z = acc[0];
                    let d = if CLAMP {
                        D::from_z(z)
                    } else {
                        D::from_z_in_range(z)
                    };
                    test.apply::<D>(d, &mut depth_row[j])
                } else {
                    true
                };
                for ch in 0..channels {
                    let v = whole(&acc, &word, color_at + ch);
                    frags.c[ch][i] = if CLAMP { v.clamp(0, 255) } else { v } as u16;
                }
                if FOG {
                    let v = whole(&acc, &word, fog_at);
                    frags.f[i] = if CLAMP { v.clamp(0, 256) } else { v } as u16;
                }
                match TEX {
                    TEX_AFFINE if words => {
                        let coord = |plane: usize| {
                            (word[tex_at + plane] >> 16).wrapping_add(uv_offsets[plane])
                        };
                        (frags.u[i], frags.v[i]) = (coord(0), coord(1));
                    }
                    TEX_AFFINE => {
                        let coord = |c: i64| {
                            if CLAMP {
                                clamp_coord(c >> 16) as i32
                            } else {
                                (c >> 16) as i32
                            }
                        };
                        (frags.u[i], frags.v[i]) = (coord(acc[tex_at]), coord(acc[tex_at + 1]));
                    }
                    TEX_PERSPECTIVE => {
                        let (s, t, q) = (acc[tex_at], acc[tex_at + 1], acc[tex_at + 2]);
                        // `divide` clamps to the coordinate range: `clamp_coord` would change
                        // nothing.
                        let (u, v) = if CLAMP {
                            divide(s, t, q)
                        } else {
                            divide_in_range(s, t, q)
                        };
                        debug_assert_eq!(clamp_coord(u >> 16), u >> 16);
                        (frags.u[i], frags.v[i]) = ((u >> 16) as i32, (v >> 16) as i32);
                    }
                    _ => {}
                }
                for (a, d) in acc.iter_mut().zip(&step) {
                    *a = a.wrapping_add(*d);
                }
                for (a, d) in word.iter_mut().zip(&word_step) {
                    *a = a.wrapping_add(*d);
                }
                k += pass as usize;
            }
            frags.keep(k);
        }
        row_at += width;
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;
    use crate::pipeline::fixed::divide;

    fn plane(dx: i64, dy: i64) -> AttrPlane {
        let mut p = AttrPlane::default();
        (p.dx, p.dy) = (dx, dy);
        p
    }

    /// Where `quotients_in_range` says so, the unclamped division equals `divide` at every pixel
    /// of the rectangle (`divide_in_range` also asserts its own bounds).
    fn check(tex: [(i64, i64, i64); 3], w: i64, h: i64) -> bool {
        let planes = tex.map(|(_, dx, dy)| plane(dx, dy));
        let start = tex.map(|(v, _, _)| v);
        let ok = quotients_in_range(&planes, &start, w, h);
        if ok {
            for row in 0..=h {
                for col in 0..=w {
                    let [s, t, q] = tex.map(|(v, dx, dy)| v + dx * col + dy * row);
                    assert_eq!(divide_in_range(s, t, q), divide(s, t, q));
                }
            }
        }
        ok
    }

    #[test]
    fn extreme_planes_neither_overflow_nor_pass_unbounded() {
        // Values and gradients at the bounds of a small triangle's narrow planes (below 2^61 and
        // 2^49): q far below zero over the rectangle once overflowed the bound's product.
        let values = [-(1 << 61), -1, 0, 1, 1 << 36, (1 << 61) - 1];
        let gradients = [-(1 << 49) + 1, -1, 0, 1, (1 << 49) - 1];
        for q in values {
            for dq in gradients {
                for s in values {
                    for ds in gradients {
                        for (w, h) in [(0, 0), (15, 15), (3, 0)] {
                            check([(s, ds, ds), (0, 0, 0), (q, dq, -dq)], w, h);
                            check([(0, 0, 0), (s, -ds, ds), (q, dq, dq)], w, h);
                        }
                    }
                }
            }
        }
        // q of one texel, coordinates within 256 repeats: no clamp needed.
        assert!(check(
            [(3 << 16, 0, 0), (-(5 << 16), 0, 0), (1 << 16, 0, 0)],
            15,
            15
        ));
        // q reaching zero in the rectangle: clamps.
        assert!(!check([(0, 0, 0), (0, 0, 0), (15, -1, 0)], 15, 15));
    }

    #[test]
    fn texture_words_at_the_edge_of_their_reach() {
        // A first pixel just below a multiple of 2^16, so the offset lies almost 2^16 below it,
        // and a step of one column up to the bound: the next pixel's word is the largest i32.
        let base = (5 << 16) - 1;
        let bound = (1i64 << 31) - (1 << 16);
        for (dx, words) in [(bound - 1, true), (bound, false), (-bound + 1, true)] {
            let tex = [AttrPlane::with(base, dx, 0), plane(0, 0), plane(0, 0)];
            let offsets = word_offsets(&tex, 1, 0);
            assert_eq!(offsets.is_some(), words, "{dx}");
            if let Some([o, _]) = offsets {
                let word = word_at(&tex[0], o, 1, 0);
                assert_eq!(i64::from(word), base + dx - o, "{dx}");
            }
        }
    }

    proptest! {
        /// Where `word_offsets` gives offsets, the words `word_at` steps give every pixel's
        /// texture coordinate of the rectangle, as the i64 plane does: values on either side of
        /// the offset, spreads up to the bound and past it, bases anywhere in the coordinates'
        /// range.
        #[test]
        fn texture_words_from_their_offsets_are_the_planes_coordinates(
            base in -(TEXCOORD_LIMIT << 16)..TEXCOORD_LIMIT << 16,
            gradients in proptest::array::uniform4(-(1i64 << 29)..1 << 29),
            w in 0i64..16,
            h in 0i64..16,
        ) {
            let [dx, dy, ex, ey] = gradients;
            let tex = [AttrPlane::with(base, dx, dy), AttrPlane::with(-base, ex, ey), plane(0, 0)];
            let Some(offsets) = word_offsets(&tex, w, h) else {
                let reach = |q: &AttrPlane| (q.dx * w).abs() + (q.dy * h).abs();
                prop_assert!(reach(&tex[0]).max(reach(&tex[1])) >= (1 << 31) - (1 << 16));
                return Ok(());
            };
            for (q, o) in tex.iter().zip(offsets) {
                prop_assert_eq!(o % (1 << 16), 0);
                for (col, row) in (0..=h).flat_map(|r| (0..=w).map(move |c| (c, r))) {
                    let word = word_at(q, o, col as i32, row as i32);
                    let coord = (word >> 16).wrapping_add((o >> 16) as i32);
                    prop_assert_eq!(i64::from(coord), q.at_pixel(col, row) >> 16);
                }
            }
        }

        #[test]
        fn quotients_in_range_only_where_no_clamp_changes_them(
            q in 1i64..1 << 36,
            dq in -(1i64 << 20)..1 << 20,
            u in -(300i64 << 16)..300 << 16,
            du in -(1i64 << 40)..1 << 40,
            w in 0i64..16,
            h in 0i64..16,
        ) {
            // s = u * q as the set-up makes it (u in 16.16, q's scale), stepped across the
            // rectangle.
            let s = ((u as i128 * q as i128) >> 16) as i64;
            check([(s, du, -du), (-s, du / 2, du), (q, dq, -dq)], w, h);
        }
    }
}
