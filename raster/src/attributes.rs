//! What the rows of one draw interpolate and how they combine it, worked out once per draw
//! from its render state: the run-time half of the state, shared by set-up, the row step and
//! the colour stage of both pipelines.

use crate::edge::SMALL;
use crate::fixed_point::{SUBPIXEL_BITS, SUBPIXEL_ONE};
use crate::state::{Compare, DepthMode, Perspective, RenderState, Shading};
use crate::texture::{MipFilter, Texture};

/// How texture coordinates are interpolated in this draw.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum TexMode {
    /// No texture.
    Off,
    /// Linear in screen space.
    Affine,
    /// Perspective-correct, exact every `n` pixels (1 = every pixel).
    Perspective(u8),
}

/// What the rows of one draw interpolate and how they combine it: the run-time half of the render
/// state (the compile-time half is the type parameters of the row functions).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Attributes<'t> {
    pub depth: bool,
    pub shade: bool,
    pub fog: bool,
    pub tex: TexMode,
    pub flat: [u8; 3],
    pub fog_color: [u8; 3],
    pub compare: Compare,
    pub depth_write: bool,
    /// How a triangle's mip level is chosen, when a texture is bound.
    mip: Option<MipChoice<'t>>,
}

impl<'t> Attributes<'t> {
    pub fn new(state: &RenderState<'t>, has_depth_buffer: bool) -> Self {
        let depth = has_depth_buffer && state.depth != DepthMode::NONE;
        let tex = match (state.texture, state.perspective) {
            (None, _) => TexMode::Off,
            (Some(_), Perspective::Affine) => TexMode::Affine,
            (Some(_), Perspective::Exact) => TexMode::Perspective(1),
            (Some(_), Perspective::Spans(n)) => TexMode::Perspective(n.clamp(2, 64)),
        };
        Self {
            depth,
            shade: state.shading == Shading::Gouraud,
            fog: state.fog.is_some(),
            tex,
            flat: match state.shading {
                Shading::Flat(c) => c,
                Shading::Gouraud => [255; 3],
            },
            fog_color: state.fog.map_or([0; 3], |f| f.color),
            compare: state.depth.compare,
            depth_write: state.depth.write,
            mip: state.texture.map(|b| {
                let t = b.texture;
                let base = &t.levels()[0];
                MipChoice {
                    texture: t,
                    per_triangle: b.sampler.mip == MipFilter::Nearest,
                    finest: usize::from(b.finest_level).min(t.levels().len() - 1) as u8,
                    texels: (base.width() * base.height()).trailing_zeros() as i32,
                }
            }),
        }
    }

    /// The interpolation a triangle uses: under `Spans(n)`, one whose bounding box fits in
    /// `n x n` pixels is linear between its exactly projected vertices, which bounds its error as
    /// an `n`-pixel span does, without a division per row. `small`: the triangle is
    /// `Coverage::is_small`. Inlined: set-up calls it once per triangle, and the call would cost
    /// more than the body.
    #[inline(always)]
    pub fn tex_mode_for(&self, xy: [[i64; 2]; 3], small: bool) -> TexMode {
        match self.tex {
            // A small triangle's vertices lie in fewer than `SMALL` pixel columns and rows,
            // less than `SMALL` pixels apart: within `n` without measuring them.
            TexMode::Perspective(n) if small && n as i64 >= SMALL => TexMode::Affine,
            TexMode::Perspective(n) if n > 1 => {
                let extent = |k: usize| {
                    let (lo, hi) = xy.iter().fold((i64::MAX, i64::MIN), |(lo, hi), p| {
                        (lo.min(p[k]), hi.max(p[k]))
                    });
                    hi - lo
                };
                let limit = n as i64 * SUBPIXEL_ONE;
                if extent(0) <= limit && extent(1) <= limit {
                    TexMode::Affine
                } else {
                    self.tex
                }
            }
            mode => mode,
        }
    }

    /// True when any attribute varies across a triangle (otherwise set-up needs no planes).
    pub fn interpolates(&self) -> bool {
        self.depth || self.shade || self.fog || self.tex != TexMode::Off
    }

    /// Mip level of a triangle from the bit length of its doubled texture-space area (16.16
    /// repeats squared; 0 for none) and its doubled screen area (sub-pixels squared), never
    /// finer than the binding's finest level. The caller measures the texture area in the width
    /// its pipeline has it in: a 128-bit one is four words on a 32-bit core.
    pub fn level(&self, texel_area2_bits: u32, area2: i64) -> u8 {
        let Some(m) = self.mip else {
            return 0;
        };
        if !m.per_triangle || texel_area2_bits == 0 || area2 <= 0 {
            return m.finest;
        }
        let ratio_log2 = texel_area2_bits as i32 - 32 + m.texels + 2 * SUBPIXEL_BITS as i32
            - (64 - area2.leading_zeros() as i32);
        m.texture
            .level_for_area_ratio(ratio_log2)
            .max(m.finest.into()) as u8
    }
}

/// A draw's mip level choice, worked out once per draw rather than per triangle.
#[derive(Clone, Copy, Debug)]
struct MipChoice<'t> {
    texture: &'t Texture,
    /// The level is chosen per triangle (nearest mip), not always the finest allowed.
    per_triangle: bool,
    /// The finest level allowed (the binding's `finest_level`, within the chain).
    finest: u8,
    /// Texels of level 0, as a power of two.
    texels: i32,
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;
    use crate::edge::{Coverage, PixelRect};

    proptest! {
        /// A small triangle's interpolation, known from `Coverage::is_small` alone, is the one
        /// its measured extents give, for every span length.
        #[test]
        fn small_triangles_take_the_mode_their_extents_give(
            origin in (-(1i64 << 20)..1 << 20, -(1i64 << 20)..1 << 20),
            offsets in prop::array::uniform3((0i64..20 * SUBPIXEL_ONE, 0i64..20 * SUBPIXEL_ONE)),
        ) {
            let xy = offsets.map(|(x, y)| [origin.0 + x, origin.1 + y]);
            let clip = PixelRect { x0: -(1 << 16), y0: -(1 << 16), x1: 1 << 16, y1: 1 << 16 };
            let texture = Texture::from_rgba8(2, 2, vec![[9; 4]; 4]).expect("a texture");
            let Some(cov) = Coverage::new(xy, clip) else {
                return Ok(());
            };
            for n in 2..=64 {
                let state = RenderState {
                    texture: Some(crate::TextureBinding::new(&texture, crate::Sampler::default())),
                    perspective: Perspective::Spans(n),
                    ..RenderState::default()
                };
                let a = Attributes::new(&state, false);
                prop_assert_eq!(a.tex_mode_for(xy, cov.is_small()), a.tex_mode_for(xy, false));
            }
        }
    }
}
