//! The colour stage one fragment at a time, for build targets whose lanes are not vectors
//! (`crate::lanes::VECTORS`: 32-bit ARM, ARMv5TE as the PocketPC's XScale and ARMv7 with or
//! without NEON). There `wide`'s vectors are arrays worked element by element (with NEON the
//! compiler makes vectors of some of that work again), a group's channels, 8 fragments of
//! 16-bit lanes, outgrow the registers and go through memory, and the bilinear RGB565 filter
//! takes 6 multiplications per channel. One fragment's colour in scalar 32-bit integers stays
//! in registers, and the filter runs in the packed form (`Texel::blend`), 6 multiplications for
//! the three channels.
//!
//! The bytes are those of the lanes: each step is the scalar twin of a lane step (the sampler's,
//! `modulate`, `fog_blend`, `pack`), and the tests below hold the two stages to equal pixels.

use super::Fragments;
use crate::attributes::Attributes;
use crate::pixel::{PixelFormat, modulate};
#[cfg(test)]
use crate::sampler::UvRange;
use crate::sampler::{Filtering, LevelView};
use crate::texture::Wrap;

impl Fragments {
    /// `colour` one fragment at a time: the held fragments' colours, each written to its pixel
    /// in the order they arrived. `inside` where the view holds their texture coordinates
    /// inside (`LevelView::holds_inside`): then no coordinate is folded or wrapped.
    #[inline(always)]
    pub(super) fn colour_one_by_one<
        P: PixelFormat,
        F: Filtering,
        const SHADE: bool,
        const GREY: bool,
        const FOG: bool,
    >(
        &self,
        view: Option<&LevelView<'_, F::Texel>>,
        a: &Attributes,
        pixels: &mut [P::Pixel],
        inside: bool,
    ) {
        if inside && let Some(view) = view.filter(|_| F::ENABLED) {
            return self.colour_each::<P, F, SHADE, GREY, FOG, true>(Some(view), a, pixels);
        }
        // A loop for each wrap, each in a view whose wrap the compiler sees as a constant: one
        // branch a buffer instead of two a fragment.
        let known = |wrap| {
            let mut v = *view.filter(|_| F::ENABLED)?;
            v.wrap = wrap;
            Some(v)
        };
        let mut each = |view: Option<LevelView<'_, F::Texel>>| {
            self.colour_each::<P, F, SHADE, GREY, FOG, false>(view.as_ref(), a, pixels)
        };
        match view.map(|v| v.wrap) {
            Some(Wrap::Repeat) => each(known(Wrap::Repeat)),
            Some(Wrap::Clamp) => each(known(Wrap::Clamp)),
            None => each(None),
        }
    }

    /// `colour_one_by_one` in a view of a known wrap, or (`INSIDE`) of none to apply.
    #[inline(always)]
    fn colour_each<
        P: PixelFormat,
        F: Filtering,
        const SHADE: bool,
        const GREY: bool,
        const FOG: bool,
        const INSIDE: bool,
    >(
        &self,
        view: Option<&LevelView<'_, F::Texel>>,
        a: &Attributes,
        pixels: &mut [P::Pixel],
    ) {
        let n = self.len;
        // Every array cut to the fragments held, so that indexing them needs no check.
        let (at, u, v, f) = (&self.at[..n], &self.u[..n], &self.v[..n], &self.f[..n]);
        let (r, g, b) = (&self.c[0][..n], &self.c[1][..n], &self.c[2][..n]);
        let view = view.filter(|_| F::ENABLED);
        let fog = Pair::of(a.fog_color);
        for k in 0..n {
            // Shading channels are 0..=255 (`Fragments::c`).
            let rgb = if !SHADE {
                a.flat
            } else if GREY {
                [r[k] as u8; 3]
            } else {
                [r[k] as u8, g[k] as u8, b[k] as u8]
            };
            let mut pair = Pair::of(rgb);
            if F::ENABLED {
                let view = view.expect("texture view bound with texturing on");
                let t = F::sample_one::<INSIDE>(view, u[k], v[k]);
                // A grey shade modulates the three channels alike: two products, not three; a
                // white flat colour leaves them as they are.
                pair = if SHADE && GREY {
                    Pair::of(t).modulated(r[k] as u32)
                } else if GREY {
                    Pair::of(t)
                } else {
                    Pair::of(modulate(t, rgb))
                };
            }
            if FOG {
                pair = pair.fogged(fog, f[k] as u32);
            }
            pixels[at[k] as usize] = P::pack(pair.rgb());
        }
    }
}

/// A colour's channels in two words of 16-bit lanes, red and blue in `rb` (bits 0 and 16),
/// green in `g`: `modulate` by a grey and `fog_blend` (one share for the three channels) then
/// take two products instead of three. Exact: each lane's product or sum of products lies
/// below `255 * 256 < 2^16`, so no lane carries into the next.
#[derive(Clone, Copy)]
pub(super) struct Pair {
    rb: u32,
    g: u32,
}

impl Pair {
    #[inline(always)]
    pub(super) fn of(c: [u8; 3]) -> Self {
        Self {
            rb: c[0] as u32 | (c[2] as u32) << 16,
            g: c[1] as u32,
        }
    }

    /// `modulate` by the grey `c` (`0..=255`) in every channel.
    #[inline(always)]
    pub(super) fn modulated(self, c: u32) -> Self {
        let m = c + 1;
        Self {
            rb: ((self.rb * m) >> 8) & 0x00ff_00ff,
            g: (self.g * m) >> 8,
        }
    }

    /// `fog_blend` towards `fog` with the share `f` (`0..=256`) of the surface colour.
    #[inline(always)]
    pub(super) fn fogged(self, fog: Self, f: u32) -> Self {
        let rest = 256 - f;
        Self {
            rb: ((self.rb * f + fog.rb * rest) >> 8) & 0x00ff_00ff,
            g: (self.g * f + fog.g * rest) >> 8,
        }
    }

    #[inline(always)]
    pub(super) fn rgb(self) -> [u8; 3] {
        [self.rb as u8, self.g as u8, (self.rb >> 16) as u8]
    }
}

#[cfg(test)]
mod tests {
    use std::fmt::Debug;

    use proptest::prelude::*;

    use super::*;
    use crate::fixed_point::TEXCOORD_LIMIT;
    use crate::fragments::CAPACITY;
    use crate::pixel::{Rgb565, Rgba8888};
    use crate::sampler::{Bilinear, Nearest, NoTexture};
    use crate::state::{Fog, RenderState, Shading};
    use crate::texture::Wrap;

    /// Pixels of the tile the fragments land in.
    const TILE: usize = 48;

    /// The held fragments coloured by the lanes, one by one and (for a filter that blends
    /// blocks) in passes, into tiles of equal pixels: the tiles must stay equal. The stages one
    /// at a time skip the wraps where the view holds the fragments' coordinates inside.
    /// Returns the lanes' tile.
    fn stages_agree<
        P: PixelFormat,
        F: Filtering,
        const SHADE: bool,
        const GREY: bool,
        const FOG: bool,
    >(
        frags: &Fragments,
        view: &LevelView<'_, F::Texel>,
        a: &Attributes,
    ) -> Result<Vec<P::Pixel>, TestCaseError>
    where
        P::Pixel: PartialEq + Debug,
    {
        let n = frags.held();
        let range = UvRange {
            lo: [frags.u, frags.v].map(|c| c[..n].iter().copied().min().unwrap_or(i32::MAX)),
            hi: [frags.u, frags.v].map(|c| c[..n].iter().copied().max().unwrap_or(i32::MIN)),
        };
        let inside = view.holds_inside(&range);
        let mut lanes = vec![P::pack([1, 2, 3]); TILE];
        let mut one = lanes.clone();
        frags.colour::<P, F, SHADE, GREY, FOG, false>(Some(view), a, &mut lanes);
        frags.colour_one_by_one::<P, F, SHADE, GREY, FOG>(Some(view), a, &mut one, inside);
        prop_assert_eq!(&lanes, &one, "SHADE {} GREY {} FOG {}", SHADE, GREY, FOG);
        if F::TAPS {
            let mut passes = lanes.clone();
            passes.fill(P::pack([1, 2, 3]));
            let mut frags = frags.clone();
            frags.colour_in_passes::<P, F, SHADE, GREY, FOG>(view, a, &mut passes);
            prop_assert_eq!(
                &lanes,
                &passes,
                "passes: SHADE {} GREY {} FOG {}",
                SHADE,
                GREY,
                FOG
            );
        }
        Ok(lanes)
    }

    /// `stages_agree` with and without shading (coloured and grey) and fog; under a white flat
    /// colour, the stages that leave the texture's colour as it is give the pixels of those
    /// that modulate it.
    fn every_state<P: PixelFormat, F: Filtering>(
        frags: &Fragments,
        view: &LevelView<'_, F::Texel>,
        a: &Attributes,
    ) -> Result<(), TestCaseError>
    where
        P::Pixel: PartialEq + Debug,
    {
        let modulated = [
            stages_agree::<P, F, false, false, false>(frags, view, a)?,
            stages_agree::<P, F, false, false, true>(frags, view, a)?,
        ];
        if F::ENABLED && a.flat == [255; 3] {
            let white = [
                stages_agree::<P, F, false, true, false>(frags, view, a)?,
                stages_agree::<P, F, false, true, true>(frags, view, a)?,
            ];
            prop_assert_eq!(white, modulated);
        }
        stages_agree::<P, F, true, false, false>(frags, view, a)?;
        stages_agree::<P, F, true, false, true>(frags, view, a)?;
        stages_agree::<P, F, true, true, false>(frags, view, a)?;
        stages_agree::<P, F, true, true, true>(frags, view, a)?;
        Ok(())
    }

    /// A fragment: its pixel, texture coordinates (near the level or anywhere within the limit),
    /// shading colour and fog share.
    fn fragment() -> impl Strategy<Value = Held> {
        let limit = TEXCOORD_LIMIT as i32;
        fragment_in(prop_oneof![-(1i32 << 17)..1 << 17, -limit..=limit])
    }

    /// A fragment whose texture coordinates `coordinate` gives.
    fn fragment_in(coordinate: impl Strategy<Value = i32> + Clone) -> impl Strategy<Value = Held> {
        (
            0..TILE as u32,
            [coordinate.clone(), coordinate],
            [0u16..=255, 0u16..=255, 0u16..=255],
            0u16..=256,
        )
    }

    /// A held fragment: its pixel, texture coordinates, shading colour and fog share.
    type Held = (u32, [i32; 2], [u16; 3], u16);

    /// A white flat colour or any.
    fn flat() -> impl Strategy<Value = [u8; 3]> {
        prop_oneof![Just([255; 3]), proptest::array::uniform3(0u8..=255)]
    }

    /// What `all_stages_agree` draws: fragments from `fragment`, the sides' powers of two, the
    /// texels of both formats, the wrap (repeat or clamp), the flat colour and fog's colour.
    type Inputs = (
        Vec<Held>,
        (u32, u32),
        Vec<u16>,
        Vec<[u8; 4]>,
        bool,
        ([u8; 3], [u8; 3]),
    );

    /// `Inputs` with fragments from `fragment`.
    fn inputs(fragment: impl Strategy<Value = Held>) -> impl Strategy<Value = Inputs> {
        (
            proptest::collection::vec(fragment, 1..=CAPACITY),
            (0u32..6, 0u32..6),
            proptest::collection::vec(proptest::num::u16::ANY, 1 << 10),
            proptest::collection::vec(proptest::array::uniform4(0u8..=255), 1 << 10),
            proptest::bool::ANY,
            (flat(), proptest::array::uniform3(0u8..=255)),
        )
    }

    proptest! {
        #[test]
        fn one_by_one_gives_the_bytes_of_the_lanes(drawn in inputs(fragment())) {
            all_stages_agree(drawn)?;
        }

        /// Coordinates within the level's repeat, held inside it by all but the smallest levels
        /// and near its edges: the stages without wraps give the bytes of the lanes.
        #[test]
        fn one_by_one_inside_the_level_gives_the_bytes_of_the_lanes(
            drawn in inputs(fragment_in(1i32 << 13..(1 << 16) - (1 << 13))),
        ) {
            all_stages_agree(drawn)?;
        }
    }

    /// `every_state` of the fragments `held` in levels of `2^sides` texels of either format
    /// (the first of `rgb565` and `rgba`), under the flat colour `flat` and fog's colour `fog`.
    fn all_stages_agree(
        (held, sides, rgb565, rgba, repeat, (flat, fog)): Inputs,
    ) -> Result<(), TestCaseError> {
        let mut frags = Fragments::new();
        for (k, &(at, [u, v], c, f)) in held.iter().enumerate() {
            let i = Fragments::slot(k);
            (frags.at[i], frags.u[i], frags.v[i], frags.f[i]) = (at, u, v, f);
            for (channel, &c) in frags.c.iter_mut().zip(&c) {
                channel[i] = c;
            }
        }
        frags.keep(held.len());
        let state = RenderState {
            shading: Shading::Flat(flat),
            fog: Some(Fog {
                color: fog,
                start: 1.0,
                end: 2.0,
            }),
            ..RenderState::default()
        };
        let a = Attributes::new(&state, false);
        let (w, h) = (1u32 << sides.0, 1u32 << sides.1);
        let n = (w * h) as usize;
        let wrap = if repeat { Wrap::Repeat } else { Wrap::Clamp };
        let v565 = LevelView::new(&rgb565[..n], w, h, wrap);
        let v8888 = LevelView::new(&rgba[..n], w, h, wrap);
        every_state::<Rgb565, NoTexture>(&frags, &v565, &a)?;
        every_state::<Rgb565, Nearest<u16>>(&frags, &v565, &a)?;
        every_state::<Rgb565, Bilinear<u16>>(&frags, &v565, &a)?;
        every_state::<Rgb565, Nearest<[u8; 4]>>(&frags, &v8888, &a)?;
        every_state::<Rgb565, Bilinear<[u8; 4]>>(&frags, &v8888, &a)?;
        every_state::<Rgba8888, NoTexture>(&frags, &v565, &a)?;
        every_state::<Rgba8888, Nearest<u16>>(&frags, &v565, &a)?;
        every_state::<Rgba8888, Bilinear<u16>>(&frags, &v565, &a)?;
        every_state::<Rgba8888, Nearest<[u8; 4]>>(&frags, &v8888, &a)?;
        every_state::<Rgba8888, Bilinear<[u8; 4]>>(&frags, &v8888, &a)
    }

    #[test]
    fn coordinates_of_the_inside_test_are_held_inside_most_levels() {
        let texels = [0u16; 64];
        let range = UvRange {
            lo: [1 << 13; 2],
            hi: [(1 << 16) - (1 << 13) - 1; 2],
        };
        let view = |w: u32, h: u32| LevelView::new(&texels[..(w * h) as usize], w, h, Wrap::Clamp);
        assert!(view(8, 8).holds_inside(&range));
        assert!(view(4, 16).holds_inside(&range));
        assert!(!view(2, 8).holds_inside(&range));
        assert!(!view(8, 1).holds_inside(&range));
    }
}
