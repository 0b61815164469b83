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
    /// Memory lent as a surface cannot hold its pixels (see [`SurfaceError`]).
    #[error("surface refused: {0}")]
    Surface(#[from] SurfaceError),
}

/// Why memory was refused as a surface.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
pub enum SurfaceError {
    /// The row stride does not hold a row of pixels.
    #[error("stride of {stride} bytes is shorter than a row of {row} bytes")]
    StrideTooSmall {
        /// Stride given.
        stride: usize,
        /// Bytes of one row's pixels.
        row: usize,
    },
    /// The row stride would start rows between pixels.
    #[error("stride of {stride} bytes is not a multiple of the {pixel}-byte pixel")]
    StrideNotWhole {
        /// Stride given.
        stride: usize,
        /// Bytes per pixel.
        pixel: usize,
    },
    /// The memory ends before the last row's last pixel.
    #[error("{got} bytes of memory are fewer than the {needed} its rows reach")]
    TooShort {
        /// Bytes needed: `stride * (height - 1) + width * bytes per pixel`.
        needed: usize,
        /// Bytes given.
        got: usize,
    },
    /// The memory does not start at a multiple of the layout's word size.
    #[error(
        "memory at address {address:#x} is not aligned to the {align}-byte words of the layout"
    )]
    Misaligned {
        /// Address of the first byte.
        address: usize,
        /// Alignment needed.
        align: usize,
    },
    /// The depth buffer is not one value per pixel.
    #[error("depth buffer holds {got} values, expected {expected} (one per pixel)")]
    DepthSize {
        /// Values needed.
        expected: usize,
        /// Values given.
        got: usize,
    },
}
