//! Bilinear sampling with 8-bit weights.

use std::marker::PhantomData;

use super::{Filtering, LevelView, ViewOf, clamp_coord};
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
    fn sample_lanes(view: &LevelView<'_, T>, u: i32x8, v: i32x8) -> Rgb8s {
        // As `sample` on folded coordinates: `tu` below 2^31, so 32-bit lanes hold it.
        let (su, sv) = view.scale_lanes(u, v);
        let half = i32x8::splat(1 << 15);
        let (tu, tv) = (su - half, sv - half);
        let byte = i32x8::splat(255);
        let (fx, fy) = (narrow((tu >> 8) & byte), narrow((tv >> 8) & byte));
        let (x0, x1) = view.column_pair_lanes(tu >> 16);
        let (y0, y1) = view.row_pair_lanes(tv >> 16);
        let quad = [(x0, y0), (x1, y0), (x0, y1), (x1, y1)]
            .map(|(x, y)| view.gather(view.index_lanes(x, y)));
        T::blend_lanes(quad, fx, fy)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
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
