//! The colour stage of bilinear fragments in passes, for 32-bit ARM with NEON (`cfg(arm_neon)`,
//! see `build.rs`): a pass works out every held fragment's 2x2 block of texels and its weights,
//! a pass reads the blocks, a pass blends, shades, fogs and packs them, and a last pass writes
//! each colour to its pixel. The first and third passes are arithmetic on arrays, which the
//! compiler makes into NEON vectors: `wide`'s lanes are arrays on that target, and the stage one
//! fragment at a time (`one_by_one`) keeps all of a fragment's work in scalar registers.
//!
//! The bytes are `one_by_one`'s: each pass is its steps (`Filtering::taps_one` and
//! `Texel::blend` are `sample_one` in two, `Pair` its shading), and the tests hold the stages to
//! equal pixels.

use super::one_by_one::Pair;
use super::{CAPACITY, Fragments};
use crate::attributes::Attributes;
use crate::pixel::{PixelFormat, modulate};
use crate::sampler::{Filtering, LevelView, Quad, Texel};
use crate::texture::Wrap;

/// The arrays between the passes that hold neither texels nor pixels: one value per fragment in
/// each, so that the compiler moves them a vector at a time.
#[cfg_attr(test, derive(Clone))]
pub(super) struct Between {
    quads: [Quad; CAPACITY],
    /// Each block's weights towards the right and the bottom.
    fx: [u32; CAPACITY],
    fy: [u32; CAPACITY],
    /// Each block's four texels (`Texel::to_word`).
    texels: [[u32; CAPACITY]; 4],
}

impl Default for Between {
    fn default() -> Self {
        Self {
            quads: [Quad::default(); CAPACITY],
            fx: [0; CAPACITY],
            fy: [0; CAPACITY],
            texels: [[0; CAPACITY]; 4],
        }
    }
}

impl Fragments {
    /// `colour` in passes, for a filter that blends blocks (`Filtering::TAPS`): the held
    /// fragments' colours, each written to its pixel in the order they arrived.
    #[inline(always)]
    pub(super) fn colour_in_passes<
        P: PixelFormat,
        F: Filtering,
        const SHADE: bool,
        const GREY: bool,
        const FOG: bool,
    >(
        &mut self,
        view: &LevelView<'_, F::Texel>,
        a: &Attributes,
        pixels: &mut [P::Pixel],
    ) {
        debug_assert!(F::TAPS);
        // Passes for each wrap, each in a view whose wrap the compiler sees as a constant.
        let known = |wrap| {
            let mut v = *view;
            v.wrap = wrap;
            v
        };
        match view.wrap {
            Wrap::Repeat => self.passes::<P, F, SHADE, GREY, FOG>(&known(Wrap::Repeat), a, pixels),
            Wrap::Clamp => self.passes::<P, F, SHADE, GREY, FOG>(&known(Wrap::Clamp), a, pixels),
        }
    }

    /// `colour_in_passes` in a view of a known wrap.
    #[inline(always)]
    fn passes<
        P: PixelFormat,
        F: Filtering,
        const SHADE: bool,
        const GREY: bool,
        const FOG: bool,
    >(
        &mut self,
        view: &LevelView<'_, F::Texel>,
        a: &Attributes,
        pixels: &mut [P::Pixel],
    ) {
        let n = self.len;
        // Every array cut to the fragments held, so that indexing them needs no check.
        let (u, v, f) = (&self.u[..n], &self.v[..n], &self.f[..n]);
        let (r, g, b) = (&self.c[0][..n], &self.c[1][..n], &self.c[2][..n]);
        let Between {
            quads,
            fx,
            fy,
            texels,
        } = &mut self.passes;
        for k in 0..n {
            let (quad, x, y) = F::taps_one::<false>(view, u[k], v[k]).expect("a filter with taps");
            (quads[k], fx[k], fy[k]) = (quad, x, y);
        }
        let [t0, t1, t2, t3] = texels;
        let blocks = t0
            .iter_mut()
            .zip(t1.iter_mut())
            .zip(t2.iter_mut())
            .zip(t3.iter_mut());
        for (&quad, (((a, b), c), d)) in quads[..n].iter().zip(blocks) {
            // SAFETY: each block's indexes come from this view (`taps_one`).
            let block = unsafe { view.quad_at(quad) };
            [*a, *b, *c, *d] = block.map(F::Texel::to_word);
        }
        let fog = Pair::of(a.fog_color);
        let mut colours = [P::pack([0; 3]); CAPACITY];
        let [t0, t1, t2, t3] = texels.each_ref().map(|t| &t[..n]);
        for k in 0..n {
            let block = [t0[k], t1[k], t2[k], t3[k]].map(F::Texel::from_word);
            let t = F::Texel::blend(block, fx[k], fy[k]);
            // Shading channels are 0..=255 (`Fragments::c`).
            let rgb = if !SHADE {
                a.flat
            } else if GREY {
                [r[k] as u8; 3]
            } else {
                [r[k] as u8, g[k] as u8, b[k] as u8]
            };
            // A grey shade modulates the three channels alike: two products, not three; a white
            // flat colour leaves them as they are.
            let mut pair = if SHADE && GREY {
                Pair::of(t).modulated(r[k] as u32)
            } else if GREY {
                Pair::of(t)
            } else {
                Pair::of(modulate(t, rgb))
            };
            if FOG {
                pair = pair.fogged(fog, f[k] as u32);
            }
            colours[k] = P::pack(pair.rgb());
        }
        for (&at, &colour) in self.at[..n].iter().zip(&colours) {
            pixels[at as usize] = colour;
        }
    }
}
