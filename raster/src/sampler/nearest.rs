//! Nearest-texel sampling.

use std::marker::PhantomData;

use super::{Filtering, LevelView, ViewOf, clamp_coord};

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
}
