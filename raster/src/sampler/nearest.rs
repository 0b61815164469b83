//! Nearest-texel sampling.

use std::marker::PhantomData;

use super::{Filtering, LevelView, ViewOf, clamp_coord};
use crate::lanes::{Rgb8s, i32x8};

/// The texel whose square contains the sample point.
pub(crate) struct Nearest<T>(PhantomData<T>);

impl<T: ViewOf> Filtering for Nearest<T> {
    const ENABLED: bool = true;
    type Texel = T;

    #[inline(always)]
    fn sample(view: &LevelView<'_, T>, u: i64, v: i64) -> [u8; 3] {
        let (u, v) = (clamp_coord(u), clamp_coord(v));
        view.fetch((u * view.width) >> 16, (v * view.height) >> 16)
            .rgb()
    }

    #[inline(always)]
    fn sample_lanes<const V3: bool>(view: &LevelView<'_, T>, u: i32x8, v: i32x8) -> Rgb8s {
        // Folded coordinates give columns and rows inside the level with no wrap left to do.
        let (su, sv) = view.scale_lanes(u, v);
        T::rgb_lanes(view.gather(view.index_lanes(su >> 16, sv >> 16)))
    }

    #[inline(always)]
    fn sample_one<const INSIDE: bool>(view: &LevelView<'_, T>, u: i32, v: i32) -> [u8; 3] {
        let (su, sv) = view.scale_for::<INSIDE>(u, v);
        view.texel(su >> 16, sv >> 16).rgb()
    }
}
