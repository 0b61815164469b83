//! Bilinear sampling with 8-bit weights.

use std::marker::PhantomData;

use super::{Filtering, LevelView, Quad, ViewOf, clamp_coord};
use crate::lanes::{Rgb8s, i32x8, narrow};

/// The four texels around the sample point, weighted by distance.
pub(crate) struct Bilinear<T>(PhantomData<T>);

impl<T: ViewOf> Filtering for Bilinear<T> {
    const ENABLED: bool = true;
    type Texel = T;

    #[inline(always)]
    fn sample(view: &LevelView<'_, T>, u: i64, v: i64) -> [u8; 3] {
        let (u, v) = (clamp_coord(u), clamp_coord(v));
        // Texel centres sit at half-texel offsets.
        let tu = u * view.width - (1 << 15);
        let tv = v * view.height - (1 << 15);
        let (x, y) = (tu >> 16, tv >> 16);
        let fx = ((tu >> 8) & 255) as u32;
        let fy = ((tv >> 8) & 255) as u32;
        T::blend(view.quad(x, y), fx, fy)
    }

    #[inline(always)]
    fn sample_lanes<const V3: bool>(view: &LevelView<'_, T>, u: i32x8, v: i32x8) -> Rgb8s {
        // As `sample` on folded coordinates: `tu` below 2^31, so 32-bit lanes hold it.
        let (su, sv) = view.scale_lanes(u, v);
        let half = i32x8::splat(1 << 15);
        let (tu, tv) = (su - half, sv - half);
        let byte = i32x8::splat(255);
        let (fx, fy) = ((tu >> 8) & byte, narrow((tv >> 8) & byte));
        let (y0, y1) = view.row_pair_lanes(tv >> 16);
        // Each row's two texels as neighbours in memory where they can be (one read per pair,
        // 16 reads instead of 32), else each texel on its own.
        let (quad, fx) = match view.neighbour_columns_lanes(tu >> 16, fx) {
            Some((x, fx)) => {
                let (a, b) = view.gather_pairs::<V3>(view.index_lanes(x, y0));
                let (c, d) = view.gather_pairs::<V3>(view.index_lanes(x, y1));
                ([a, b, c, d], fx)
            }
            None => {
                let (x0, x1) = view.column_pair_lanes(tu >> 16);
                let quad = [(x0, y0), (x1, y0), (x0, y1), (x1, y1)]
                    .map(|(x, y)| view.gather(view.index_lanes(x, y)));
                (quad, fx)
            }
        };
        T::blend_lanes(quad, narrow(fx), fy)
    }

    /// As `sample_lanes` with each texel of the block read on its own: the wrapped pair of
    /// columns blends to what `neighbour_columns_lanes`' pair does.
    #[inline(always)]
    fn sample_one<const INSIDE: bool>(view: &LevelView<'_, T>, u: i32, v: i32) -> [u8; 3] {
        let (quad, fx, fy) = taps::<T, INSIDE>(view, u, v);
        // SAFETY: the block's indexes come from this view.
        T::blend(unsafe { view.quad_at(quad) }, fx, fy)
    }

    #[cfg(any(test, arm_neon))]
    const TAPS: bool = true;

    #[cfg(any(test, arm_neon))]
    #[inline(always)]
    fn taps_one<const INSIDE: bool>(
        view: &LevelView<'_, T>,
        u: i32,
        v: i32,
    ) -> Option<(Quad, u32, u32)> {
        Some(taps::<T, INSIDE>(view, u, v))
    }
}

/// `sample_one`'s block and weights, from `sample_lanes`' addressing of one lane; `INSIDE`
/// without the fold and the wrap that leave such a coordinate's block as it is.
#[inline(always)]
fn taps<T: ViewOf, const INSIDE: bool>(
    view: &LevelView<'_, T>,
    u: i32,
    v: i32,
) -> (Quad, u32, u32) {
    let (su, sv) = view.scale_for::<INSIDE>(u, v);
    let (tu, tv) = (su - (1 << 15), sv - (1 << 15));
    let (fx, fy) = ((tu >> 8) & 255, (tv >> 8) & 255);
    let (x, y) = (tu >> 16, tv >> 16);
    let quad = if INSIDE {
        view.quad_inside(x, y)
    } else {
        view.quad_taps(x, y)
    };
    (quad, fx as u32, fy as u32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::isa::{Cpu, InstructionSet};
    use crate::texture::Wrap;

    fn view(texels: &[u16], wrap: Wrap) -> LevelView<'_, u16> {
        LevelView::new(texels, 2, 2, wrap)
    }

    #[test]
    fn bilinear_at_texel_centres_returns_the_texel_and_blends_between() {
        let t = [0xFFFF, 0x0000, 0x0000, 0xFFFF];
        let v = view(&t, Wrap::Clamp);
        assert_eq!(Bilinear::<u16>::sample(&v, 1 << 14, 1 << 14), [255; 3]);
        assert_eq!(Bilinear::<u16>::sample(&v, 3 << 14, 1 << 14), [0; 3]);
        let mid = Bilinear::<u16>::sample(&v, 1 << 15, 1 << 14);
        assert!(mid.iter().all(|&c| (120..=136).contains(&c)), "{mid:?}");
    }

    /// `sample_lanes` at eight points against `sample` and `sample_one` at each of them, on
    /// levels whose texels all differ; where the CPU runs the x86-64-v3 twins, their lanes (an
    /// AVX2 gather of the texel pairs) against the baseline's.
    fn lanes_match_samples<T: ViewOf>(texels: &[T], w: u32, h: u32, points: &[(i32, i32)]) {
        let v3 = Cpu::new(InstructionSet::Detected).v3();
        for wrap in [Wrap::Clamp, Wrap::Repeat] {
            let view = LevelView::new(texels, w, h, wrap);
            for group in points.chunks(8) {
                let mut p = [(0, 0); 8];
                for (k, q) in p.iter_mut().enumerate() {
                    *q = group[k % group.len()];
                }
                let (u, v) = (p.map(|q| q.0), p.map(|q| q.1));
                let lanes =
                    Bilinear::<T>::sample_lanes::<false>(&view, i32x8::new(u), i32x8::new(v));
                let twin = v3.then(|| {
                    Bilinear::<T>::sample_lanes::<true>(&view, i32x8::new(u), i32x8::new(v))
                });
                for (k, &(u, v)) in p.iter().enumerate() {
                    let one = Bilinear::<T>::sample(&view, u as i64, v as i64);
                    assert_eq!(lanes.lane(k), one, "{w}x{h} {wrap:?} at ({u}, {v})");
                    let scalar = Bilinear::<T>::sample_one::<false>(&view, u, v);
                    assert_eq!(scalar, one, "one by one, {w}x{h} {wrap:?} at ({u}, {v})");
                    if let Some(twin) = &twin {
                        assert_eq!(twin.lane(k), one, "AVX2, {w}x{h} {wrap:?} at ({u}, {v})");
                    }
                }
            }
        }
    }

    /// Texels of a `w x h` level, each its own colour in both formats.
    fn distinct(w: u32, h: u32) -> (Vec<u16>, Vec<[u8; 4]>) {
        let n = w * h;
        let rgba: Vec<[u8; 4]> = (0..n)
            .map(|i| {
                [
                    (i * 37 % 251) as u8,
                    (i * 91 % 241) as u8,
                    (i * 13 % 239) as u8,
                    255,
                ]
            })
            .collect();
        let rgb565 = (0..n).map(|i| (i * 2749 % 65521) as u16).collect();
        (rgb565, rgba)
    }

    #[test]
    fn lanes_read_neighbours_as_pairs_and_blend_as_single_samples_at_every_edge() {
        // Coordinates across both edges of the level and beyond, at fractions that put the
        // bilinear pair on either side of a texel centre: the pair reads (`gather_pairs`), the
        // clamped edge's weight of 0 or 256, and the wrap at the last column all give what
        // each texel on its own gives.
        for (w, h) in [(1, 1), (2, 1), (1, 4), (2, 2), (4, 2), (8, 8), (64, 4)] {
            let (rgb565, rgba) = distinct(w, h);
            let step = (1 << 16) / (4 * w as i32) + 37;
            let points: Vec<(i32, i32)> = (-6 * w as i32..6 * w as i32)
                .map(|k| (k * step, (k * 7919) % (3 << 16)))
                .collect();
            lanes_match_samples(&rgb565, w, h, &points);
            lanes_match_samples(&rgba, w, h, &points);
        }
    }

    proptest::proptest! {
        #[test]
        fn lanes_blend_as_single_samples(
            shift in (0u32..7, 0u32..7),
            points in proptest::collection::vec((-(1i32 << 24)..1 << 24, -(1i32 << 24)..1 << 24), 1..24),
        ) {
            let (w, h) = (1 << shift.0, 1 << shift.1);
            let (rgb565, rgba) = distinct(w, h);
            lanes_match_samples(&rgb565, w, h, &points);
            lanes_match_samples(&rgba, w, h, &points);
        }
    }

    #[test]
    fn repeat_wraps_and_clamp_holds_the_edge() {
        let t = [0xFFFF, 0x0000, 0x0000, 0x0000];
        let r = view(&t, Wrap::Repeat);
        let c = view(&t, Wrap::Clamp);
        // u = 1.25 repeats to 0.25 (texel 0); clamped it is the right edge (texel 1).
        assert_eq!(
            super::super::Nearest::<u16>::sample(&r, 5 << 14, 0),
            [255; 3]
        );
        assert_eq!(super::super::Nearest::<u16>::sample(&c, 5 << 14, 0), [0; 3]);
    }

    #[test]
    fn quads_read_the_wrapped_texels_at_every_offset() {
        let t: Vec<u16> = (0..8 * 4).collect();
        for wrap in [Wrap::Clamp, Wrap::Repeat] {
            let v = LevelView::new(&t, 8, 4, wrap);
            for y in -20..20 {
                for x in -20..20 {
                    let at = |x: i64, y: i64| t[(v.row(y) * 8 + v.column(x)) as usize];
                    let expected = [at(x, y), at(x + 1, y), at(x, y + 1), at(x + 1, y + 1)];
                    assert_eq!(v.quad(x, y), expected, "{wrap:?} {x},{y}");
                    assert_eq!(v.fetch(x, y), at(x, y));
                }
            }
        }
    }

    #[test]
    #[should_panic]
    fn a_view_whose_texels_do_not_fill_it_is_refused() {
        let t = [0u16; 7];
        let _ = LevelView::new(&t, 4, 2, Wrap::Repeat);
    }

    #[test]
    fn wrapped_pairs_equal_wrapping_each_coordinate() {
        let t = [0u16; 16 * 4];
        for wrap in [Wrap::Clamp, Wrap::Repeat] {
            let v = LevelView::new(&t, 16, 4, wrap);
            for k in -40..40 {
                assert_eq!(
                    v.column_pair(k),
                    (v.column(k), v.column(k + 1)),
                    "{wrap:?} {k}"
                );
                assert_eq!(v.row_pair(k), (v.row(k), v.row(k + 1)), "{wrap:?} {k}");
            }
        }
    }
}
