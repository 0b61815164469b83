//! Render state as small `Copy` types with named constants: a draw names what it needs, and the
//! pipeline picks a specialised inner loop for exactly that set.

use crate::RasterError;
use crate::texture::{Sampler, Texture};

/// Which arithmetic runs the pipeline.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Precision {
    /// Integer fixed point from transform to pixel: the fast path, and what an FPU-less device runs.
    #[default]
    Fixed,
    /// The f32 reference twin: same coverage rules on the same sub-pixel grid, float everything else.
    Float,
}

/// Which faces are dropped.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum CullMode {
    /// Draw both faces.
    #[default]
    None,
    /// Drop back faces.
    Back,
    /// Drop front faces.
    Front,
}

/// Which winding, seen in normalised device coordinates (y up), is the front.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum FrontFace {
    /// Counter-clockwise is front (OpenGL's default).
    #[default]
    Ccw,
    /// Clockwise is front.
    Cw,
}

/// Depth comparison: a fragment passes when `new OP stored`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Compare {
    /// Always passes.
    Always,
    /// Nearer passes.
    Less,
    /// Nearer or equal passes.
    LessEqual,
}

/// Depth test and write together.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct DepthMode {
    /// The comparison.
    pub compare: Compare,
    /// Whether passing fragments store their depth.
    pub write: bool,
}

impl DepthMode {
    /// No depth test and no depth write: the depth buffer is not touched.
    pub const NONE: Self = Self {
        compare: Compare::Always,
        write: false,
    };
    /// The usual opaque-geometry mode.
    pub const LESS_WRITE: Self = Self {
        compare: Compare::Less,
        write: true,
    };
    /// Like `LESS_WRITE`, but equal depths pass (for re-drawing the same surface).
    pub const LESS_EQUAL_WRITE: Self = Self {
        compare: Compare::LessEqual,
        write: true,
    };
    /// Test without writing.
    pub const LESS_READ_ONLY: Self = Self {
        compare: Compare::Less,
        write: false,
    };

    /// True when the depth buffer is read or written.
    pub fn is_enabled(self) -> bool {
        self != Self::NONE
    }
}

impl Default for DepthMode {
    fn default() -> Self {
        Self::LESS_WRITE
    }
}

/// How colour varies across a triangle.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Shading {
    /// One colour for every pixel (multiplied with the texture when there is one).
    Flat([u8; 3]),
    /// Vertex colours interpolated across the triangle (Gouraud).
    Gouraud,
}

impl Default for Shading {
    fn default() -> Self {
        Self::Flat([255; 3])
    }
}

/// Perspective correction of texture coordinates: the project's first speed/accuracy knob.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Perspective {
    /// One division per pixel: exact.
    Exact,
    /// Exact at every `n`-th pixel, linear in between (Quake-style spans). `n` is clamped to 2..=64.
    Spans(u8),
    /// Linear in screen space: no division at all; wrong under strong perspective.
    Affine,
}

impl Default for Perspective {
    fn default() -> Self {
        Self::Spans(16)
    }
}

/// Linear fog by eye distance (the clip `w` of a perspective projection).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fog {
    /// Colour far away.
    pub color: [u8; 3],
    /// Distance where fog starts, in the transform's output units.
    pub start: f64,
    /// Distance where fog is total.
    pub end: f64,
}

/// A texture and how to read it.
#[derive(Clone, Copy, Debug)]
pub struct TextureBinding<'t> {
    /// The texture with its mip chain.
    pub texture: &'t Texture,
    /// Filter, mipmapping and wrap.
    pub sampler: Sampler,
    /// The finest mip level this draw may read (clamped to the chain), whatever the triangle's
    /// screen size asks for: a caller that knows an object matters little (the terrain engine's
    /// importance budget) caps its texture detail here, as GL's base level does.
    pub finest_level: u8,
}

impl<'t> TextureBinding<'t> {
    /// `texture` read with `sampler`, every level allowed.
    pub fn new(texture: &'t Texture, sampler: Sampler) -> Self {
        Self {
            texture,
            sampler,
            finest_level: 0,
        }
    }
}

/// A pixel rectangle, `x0..x1` by `y0..y1`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Rect {
    /// Left, inclusive.
    pub x0: u32,
    /// Top, inclusive.
    pub y0: u32,
    /// Right, exclusive.
    pub x1: u32,
    /// Bottom, exclusive.
    pub y1: u32,
}

impl Rect {
    /// The pixels a draw with `scissor` may touch on a `width x height` target: the whole target
    /// without one, or the scissor if it lies inside the target. Every backend checks it alike.
    pub fn scissor_on(scissor: Option<Rect>, width: u32, height: u32) -> Result<Rect, RasterError> {
        let r = scissor.unwrap_or(Rect {
            x0: 0,
            y0: 0,
            x1: width,
            y1: height,
        });
        if r.x0 > r.x1 || r.y0 > r.y1 || r.x1 > width || r.y1 > height {
            return Err(RasterError::Scissor {
                x0: r.x0,
                y0: r.y0,
                x1: r.x1,
                y1: r.y1,
                width,
                height,
            });
        }
        Ok(r)
    }
}

/// Everything a draw needs besides geometry and transform.
#[derive(Clone, Copy, Debug, Default)]
pub struct RenderState<'t> {
    /// Fixed or float pipeline.
    pub precision: Precision,
    /// Face culling.
    pub cull: CullMode,
    /// Front-face winding.
    pub front_face: FrontFace,
    /// Depth test and write (ignored when the framebuffer has no depth buffer).
    pub depth: DepthMode,
    /// Flat or Gouraud colour.
    pub shading: Shading,
    /// Texture, if any; modulated by the shading colour.
    pub texture: Option<TextureBinding<'t>>,
    /// Perspective correction of texture coordinates.
    pub perspective: Perspective,
    /// Fog, if any.
    pub fog: Option<Fog>,
    /// Pixels outside this rectangle are never written; `None` means the whole framebuffer.
    pub scissor: Option<Rect>,
}
