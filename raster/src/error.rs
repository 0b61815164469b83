//! The rasterizer's one error type.

use thiserror::Error;

/// What can go wrong in a draw or when building its inputs. Geometry itself never errors: any
/// finite input is drawn or clipped.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
pub enum RasterError {
    /// The transform holds a NaN or an infinity.
    #[error("transform has a non-finite entry")]
    NonFiniteTransform,
    /// A model origin beyond ±`MAX_ORIGIN` per axis.
    #[error("model origin {origin:?} is beyond ±2^24 per axis")]
    OriginOutOfRange {
        /// The origin asked for.
        origin: [i32; 3],
    },
    /// An index points past the vertex buffer.
    #[error("index {value} at position {position} is out of range for {vertices} vertices")]
    IndexOutOfRange {
        /// Position in the index buffer.
        position: usize,
        /// The index.
        value: u32,
        /// Vertex count.
        vertices: usize,
    },
    /// Framebuffer side is zero or above `MAX_DIMENSION`.
    #[error("framebuffer size {width}x{height} is outside 1..=8192 per side")]
    FramebufferSize {
        /// Width.
        width: u32,
        /// Height.
        height: u32,
    },
    /// Texture side is not a power of two (or above 32768).
    #[error("texture size {width}x{height}: sides must be powers of two up to 32768")]
    TextureSize {
        /// Width.
        width: u32,
        /// Height.
        height: u32,
    },
    /// Texel count does not match the size.
    #[error("texture data holds {got} texels, expected {expected}")]
    TextureData {
        /// Expected texels.
        expected: usize,
        /// Given texels.
        got: usize,
    },
    /// Stored mip levels do not form a chain.
    #[error("mip levels must halve down to 1x1 in one format")]
    MipChain,
    /// Scissor rectangle leaves the framebuffer or is inverted.
    #[error("scissor {x0},{y0}..{x1},{y1} does not fit the {width}x{height} framebuffer")]
    Scissor {
        /// Left.
        x0: u32,
        /// Top.
        y0: u32,
        /// Right.
        x1: u32,
        /// Bottom.
        y1: u32,
        /// Framebuffer width.
        width: u32,
        /// Framebuffer height.
        height: u32,
    },
}
