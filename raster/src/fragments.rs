//! Fragments waiting for their colour, and the colour stage that finishes them 8 at a time.
//!
//! A tile's rows are shaded in two steps. The row step (`pipeline::fixed::run_fragments`, or the
//! small-triangle loop in `small.rs`) walks a run pixel by pixel in scalar integers: depth test
//! and write, and the per-pixel values that the colour needs (texture coordinates, shading,
//! fog), which it stores here for the fragments that pass the depth test, each with its pixel.
//! When the buffer is full, or the draw's triangles in the tile are done, the colour step runs
//! over everything held in lanes of 8 (texel addressing, the filter, modulation, fog, packing;
//! only the texel reads are scalar) and writes each colour to its pixel. Terrain triangles own a
//! few pixels per row, so the buffer gathers the rows of several triangles into each group of
//! lanes. Where `wide`'s lanes are not vectors (32-bit ARM; `lanes::VECTORS`), the colour step
//! runs one fragment at a time instead (`one_by_one`).
//!
//! The bytes are those of shading each pixel on its own: every lane function equals its scalar
//! twin exactly (tested), and the colour is written in the order the fragments arrived, so a
//! later triangle's pixel still lands over an earlier one's.

mod coords;
mod one_by_one;
#[cfg(any(test, arm_neon))]
mod passes;

use crate::attributes::Attributes;
use crate::isa::{Cpu, v3_twin};
use crate::lanes::{LANES, Rgb8s, VECTORS, load_i32, load_u16};
use crate::pixel::PixelFormat;
use crate::sampler::{Filtering, LevelView, UvRange};
use crate::tile_view::TileBuf;
use coords::Coords;

/// Fragments held before their colour is computed: a tile row's worth.
pub(crate) const CAPACITY: usize = 64;
/// Length of the per-fragment arrays: a power of two above `CAPACITY + LANES` (a last group of
/// lanes reads past the fragments held), so that an index masked with `SLOTS - 1` needs no
/// bounds check.
const SLOTS: usize = 128;
const _: () = assert!(SLOTS.is_power_of_two() && SLOTS >= CAPACITY + LANES);

/// Fragments held for the colour stage (see the module documentation): only those that passed
/// the depth test, in slots `0..len`. The per-fragment arrays are public for the row steps that
/// fill them by index: from `held()` on, each at its `slot`, taking a slot only when the
/// fragment passes, then handing the count back with `keep`.
#[cfg_attr(test, derive(Clone))]
pub(crate) struct Fragments {
    len: usize,
    /// Index in the tile's buffers of the fragment's pixel (a tile holds at most
    /// `MAX_DIMENSION^2 = 2^26` pixels).
    pub at: [u32; SLOTS],
    /// Texture coordinates, 16.16 within `TEXCOORD_LIMIT`.
    pub u: [i32; SLOTS],
    pub v: [i32; SLOTS],
    /// Shading colour, 0..=255 per channel (only the first with one channel).
    pub c: [[u16; SLOTS]; 3],
    /// Share of the surface colour against fog, 0..=256.
    pub f: [u16; SLOTS],
    /// The mip level of the triangles whose fragments are held, and whether their shading is
    /// one channel (grey): fragments held together share both.
    level: usize,
    grey: bool,
    /// The range of the held fragments' texture coordinates, where the colour stage uses it
    /// (`keep_within`).
    coords: Coords,
    /// Fragments written so far.
    written: u64,
    /// The colour stage in passes' arrays between its passes, here rather than on the stack,
    /// where they would be zeroed for every buffer.
    #[cfg(any(test, arm_neon))]
    passes: passes::Between,
}

impl Fragments {
    pub fn new() -> Self {
        Self {
            len: 0,
            at: [0; SLOTS],
            u: [0; SLOTS],
            v: [0; SLOTS],
            c: [[0; SLOTS]; 3],
            f: [0; SLOTS],
            level: 0,
            grey: false,
            coords: Coords::new(),
            written: 0,
            #[cfg(any(test, arm_neon))]
            passes: passes::Between::default(),
        }
    }

    /// Readies the empty buffer for another tile: the slots past the fragments held keep
    /// pixels of the tile they are coloured into (see `colour`), and 0 lies in every tile.
    pub fn for_another_tile(&mut self) {
        debug_assert_eq!(self.len, 0);
        self.at = [0; SLOTS];
    }

    /// The fragments written so far.
    pub fn written(&self) -> u64 {
        self.written
    }

    /// True when fragments of a triangle with this level and shading may join those held.
    #[inline]
    pub fn accepts(&self, level: usize, grey: bool) -> bool {
        self.len == 0 || (self.level == level && self.grey == grey)
    }

    /// Makes the held fragments' triangles of this level and shading (nothing may be held).
    #[inline]
    pub fn hold(&mut self, level: usize, grey: bool) {
        debug_assert!(self.len == 0 || (self.level, self.grey) == (level, grey));
        (self.level, self.grey) = (level, grey);
    }

    /// Fragments that fit before the buffer is full.
    #[inline(always)]
    pub fn room(&self) -> usize {
        CAPACITY - self.len
    }

    /// The count of the next fragment: a row step that checked `room()` for its run fills
    /// slots from here (`slot`) and returns the new count with `keep`.
    #[inline(always)]
    pub fn held(&self) -> usize {
        self.len
    }

    /// Where the fragment counted `k` goes in the per-fragment arrays (`k` stays below
    /// `CAPACITY` for a row step that checked `room()`): masked, so that the index needs no
    /// bounds check.
    #[inline(always)]
    pub fn slot(k: usize) -> usize {
        k & (SLOTS - 1)
    }

    /// Holds the fragments up to slot `len`, filled by a row step since `held()`, with texture
    /// coordinates anywhere.
    #[inline(always)]
    pub fn keep(&mut self, len: usize) {
        self.keep_within(len, || None);
    }

    /// `keep` of fragments whose texture coordinates lie in `range()` (anywhere for `None`),
    /// asked only where the colour stage uses it (`coords`).
    #[inline(always)]
    pub fn keep_within(&mut self, len: usize, range: impl FnOnce() -> Option<UvRange>) {
        debug_assert!(self.len <= len && len <= CAPACITY);
        self.len = len;
        self.coords.held(range);
    }

    /// Colours the held fragments and writes them into `color`, in the order they arrived;
    /// empties the buffer. `views` are the draw's texture levels.
    ///
    /// Not inlined: it runs once per full buffer, and inlined at every call site it built the
    /// colour stage again in each of the row loops' specialisations. Runs the x86-64-v3 twin
    /// where `cpu` allows (what each costs: docs/raster.md, *Where the time goes*).
    #[inline(never)]
    pub fn finish<P: PixelFormat, F: Filtering, const SHADE: bool, const FOG: bool>(
        &mut self,
        color: &mut TileBuf<'_, P::Pixel>,
        views: &[LevelView<'_, F::Texel>],
        a: &Attributes,
        cpu: Cpu,
    ) {
        if cpu.v3() {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `cpu.v3()` holds only where the CPU has every feature the twin is built for.
            return unsafe { self.finish_v3::<P, F, SHADE, FOG>(color, views, a) };
        }
        self.finish_in::<P, F, SHADE, FOG, false>(color, views, a)
    }

    v3_twin! {
        /// `finish` built for x86-64-v3 (see `crate::isa`).
        fn finish_v3<P: PixelFormat, F: Filtering, const SHADE: bool, const FOG: bool>(
            &mut self,
            color: &mut TileBuf<'_, P::Pixel>,
            views: &[LevelView<'_, F::Texel>],
            a: &Attributes,
        ) {
            self.finish_in::<P, F, SHADE, FOG, true>(color, views, a)
        }
    }

    /// The colour stage of `finish`, built into each of its twins.
    #[inline(always)]
    fn finish_in<
        P: PixelFormat,
        F: Filtering,
        const SHADE: bool,
        const FOG: bool,
        const V3: bool,
    >(
        &mut self,
        color: &mut TileBuf<'_, P::Pixel>,
        views: &[LevelView<'_, F::Texel>],
        a: &Attributes,
    ) {
        if self.len == 0 {
            return;
        }
        let view = views.get(self.level);
        let pixels = color.pixels();
        // A white flat colour leaves the texture's as it is (`modulate` by 255 is exact): the
        // engine's unlit textured terrain skips the products.
        let white = !SHADE && F::ENABLED && a.flat == [255; 3];
        let n = self.len;
        debug_assert!(
            !F::ENABLED || self.coords.covers(&self.u[..n], &self.v[..n]),
            "texture coordinates outside the range their row step named"
        );
        let inside = F::ENABLED && self.coords.inside(view);
        // The colour stages' `GREY` (see `colour`).
        match (VECTORS, (SHADE && self.grey) || white) {
            (true, true) => self.colour::<P, F, SHADE, true, FOG, V3>(view, a, pixels),
            (true, false) => self.colour::<P, F, SHADE, false, FOG, V3>(view, a, pixels),
            #[cfg(arm_neon)]
            (false, grey) if F::TAPS => {
                let view = view.expect("texture view bound with texturing on");
                match grey {
                    true => self.colour_in_passes::<P, F, SHADE, true, FOG>(view, a, pixels),
                    false => self.colour_in_passes::<P, F, SHADE, false, FOG>(view, a, pixels),
                }
            }
            (false, true) => {
                self.colour_one_by_one::<P, F, SHADE, true, FOG>(view, a, pixels, inside)
            }
            (false, false) => {
                self.colour_one_by_one::<P, F, SHADE, false, FOG>(view, a, pixels, inside)
            }
        }
        self.written += self.len as u64;
        self.len = 0;
        self.coords.emptied();
    }

    /// Colours the held fragments a group of lanes at a time (the last group's lanes past them
    /// are coloured too, and dropped) and writes each group's to their `pixels`. `GREY`: one
    /// shading channel serves the three, or, without shading, the flat colour is white.
    #[allow(clippy::needless_range_loop)]
    #[inline(always)]
    fn colour<
        P: PixelFormat,
        F: Filtering,
        const SHADE: bool,
        const GREY: bool,
        const FOG: bool,
        const V3: bool,
    >(
        &self,
        view: Option<&LevelView<'_, F::Texel>>,
        a: &Attributes,
        pixels: &mut [P::Pixel],
    ) {
        // In the x86-64-v3 twin, every slot's pixel is checked against the tile once per
        // buffer (the 64 slots' maximum, in lanes), not at each store below: slots past the
        // held fragments keep earlier ones' pixels of the same tile, or 0. The row steps index
        // the tile they walk, so this never fails. Elsewhere, without a maximum of unsigned
        // lanes (SSE2), each store is checked: that cost less.
        let in_tile = V3 && {
            let most = self.at[..CAPACITY].iter().fold(0, |m, &at| m.max(at));
            assert!(
                (most as usize) < pixels.len(),
                "a fragment outside its tile"
            );
            true
        };
        let mut store = |at: u32, packed: P::Pixel| {
            if in_tile {
                // SAFETY: `at` is a slot's pixel, below `pixels.len()` (checked above).
                unsafe { *pixels.get_unchecked_mut(at as usize) = packed };
            } else {
                pixels[at as usize] = packed;
            }
        };
        for g in (0..self.len).step_by(LANES) {
            let mut rgb = if !SHADE {
                Rgb8s::splat(a.flat)
            } else if GREY {
                Rgb8s::grey(load_u16(&self.c[0], g))
            } else {
                Rgb8s {
                    r: load_u16(&self.c[0], g),
                    g: load_u16(&self.c[1], g),
                    b: load_u16(&self.c[2], g),
                }
            };
            if F::ENABLED {
                let view = view.expect("texture view bound with texturing on");
                let t = F::sample_lanes::<V3>(view, load_i32(&self.u, g), load_i32(&self.v, g));
                rgb = if !SHADE && GREY {
                    t
                } else {
                    crate::lanes::modulate(t, rgb)
                };
            }
            if FOG {
                rgb = crate::lanes::fog_blend(rgb, a.fog_color, load_u16(&self.f, g));
            }
            let (packed, at) = (P::pack_lanes(rgb), &self.at[g..g + LANES]);
            // A full group's stores with a constant count, which the compiler unrolls (indexed,
            // as zipped iterators cost more on x86-64); only the last group may be part-filled.
            if g + LANES <= self.len {
                for l in 0..LANES {
                    store(at[l], packed[l]);
                }
            } else {
                for l in 0..self.len - g {
                    store(at[l], packed[l]);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::edge::PixelRect;
    use crate::isa::InstructionSet;
    use crate::pixel::Rgba8888;
    use crate::sampler::NoTexture;
    use crate::state::RenderState;

    /// Holds fragments at `pixels` of a 4x3 tile, fragment `k` with colour `(k, 2k, 3k)`, and
    /// colours them on `set`'s twin.
    fn draw(pixels: &[u32], set: InstructionSet) -> Vec<[u8; 4]> {
        let rect = PixelRect {
            x0: 8,
            y0: 4,
            x1: 12,
            y1: 7,
        };
        let mut tile = TileBuf::new(rect, vec![[0; 4]; 12]);
        let attrs = Attributes::new(&RenderState::default(), false);
        let mut frags = Fragments::new();
        frags.hold(0, false);
        for (k, &at) in pixels.iter().enumerate() {
            let i = Fragments::slot(k);
            frags.at[i] = at;
            for (ch, c) in frags.c.iter_mut().enumerate() {
                c[i] = (k * (ch + 1)) as u16;
            }
        }
        frags.keep(pixels.len());
        frags.finish::<Rgba8888, NoTexture, true, false>(&mut tile, &[], &attrs, Cpu::new(set));
        assert_eq!(frags.written(), pixels.len() as u64);
        tile.pixels().to_vec()
    }

    /// Each colour lands on its pixel, a later fragment's over an earlier one's, in a full group
    /// of lanes and a part-filled one, on every instruction set the CPU runs.
    #[test]
    fn colours_land_on_their_pixels_in_arrival_order() {
        let pixels = [3, 0, 11, 5, 3, 7, 1, 2, 11, 4, 9];
        for set in [InstructionSet::Detected, InstructionSet::Baseline] {
            let tile = draw(&pixels, set);
            let mut expected = vec![[0u8; 4]; 12];
            for (k, &at) in pixels.iter().enumerate() {
                let k = k as u8;
                expected[at as usize] = [k, 2 * k, 3 * k, 255];
            }
            assert_eq!(tile, expected, "{set:?}");
        }
    }

    /// A fragment outside its tile stops the colour stage, on the twin that checks the buffer
    /// once as on the one that checks each store, before anything is written out of bounds.
    #[test]
    fn a_fragment_outside_its_tile_is_refused() {
        for set in [InstructionSet::Detected, InstructionSet::Baseline] {
            let outside = std::panic::catch_unwind(|| draw(&[3, 12, 5], set));
            assert!(outside.is_err(), "{set:?}");
        }
    }
}
