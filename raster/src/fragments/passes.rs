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
        &self,
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
        &self,
        view: &LevelView<'_, F::Texel>,
        a: &Attributes,
        pixels: &mut [P::Pixel],
    ) {
        let n = self.len;
        // Every array cut to the fragments held, so that indexing them needs no check.
        let (u, v, f) = (&self.u[..n], &self.v[..n], &self.f[..n]);
        let (r, g, b) = (&self.c[0][..n], &self.c[1][..n], &self.c[2][..n]);
        // One value per fragment in each array the arithmetic passes read or write: the
        // compiler then moves them a vector at a time.
        let mut quads = [Quad::default(); CAPACITY];
        let (mut fx, mut fy) = ([0u32; CAPACITY], [0u32; CAPACITY]);
        for k in 0..n {
            let (quad, x, y) = F::taps_one(view, u[k], v[k]).expect("a filter with taps");
            (quads[k], fx[k], fy[k]) = (quad, x, y);
        }
        let mut texels = [[F::Texel::default(); CAPACITY]; 4];
        let [t0, t1, t2, t3] = &mut texels;
        let blocks = t0
            .iter_mut()
            .zip(t1.iter_mut())
            .zip(t2.iter_mut())
            .zip(t3.iter_mut());
        for (&quad, (((a, b), c), d)) in quads[..n].iter().zip(blocks) {
            // SAFETY: each block's indexes come from this view (`taps_one`).
            [*a, *b, *c, *d] = unsafe { view.quad_at(quad) };
        }
        let fog = Pair::of(a.fog_color);
        let mut colours = [P::pack([0; 3]); CAPACITY];
        let [t0, t1, t2, t3] = texels.each_ref().map(|t| &t[..n]);
        for k in 0..n {
            let t = F::Texel::blend([t0[k], t1[k], t2[k], t3[k]], fx[k], fy[k]);
            // Shading channels are 0..=255 (`Fragments::c`).
            let rgb = if !SHADE {
                a.flat
            } else if GREY {
                [r[k] as u8; 3]
            } else {
                [r[k] as u8, g[k] as u8, b[k] as u8]
            };
            // A grey shade modulates the three channels alike: two products, not three.
            let mut pair = if SHADE && GREY {
                Pair::of(t).modulated(r[k] as u32)
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
