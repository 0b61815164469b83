//! Depth formats and storage, owned by a [`crate::Framebuffer`] or lent with a
//! [`crate::Surface`].

/// Depth-buffer format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DepthFormat {
    /// No depth buffer.
    None,
    /// 16 bits: half the memory traffic, visible z-fighting at grazing angles far away.
    D16,
    /// 32 bits.
    D32,
}

impl DepthFormat {
    /// Bytes a pixel's depth takes.
    pub(crate) fn bytes(self) -> usize {
        match self {
            DepthFormat::None => 0,
            DepthFormat::D16 => 2,
            DepthFormat::D32 => 4,
        }
    }
}

/// Depth storage; 0 is the near plane, the maximum the far plane.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum DepthBuffer {
    /// None.
    None,
    /// 16-bit values.
    D16(Vec<u16>),
    /// 32-bit values.
    D32(Vec<u32>),
}

impl DepthBuffer {
    /// A depth buffer of `width * height` values at the far plane, for a [`crate::Surface`]
    /// (kept by the caller from frame to frame).
    pub fn new(width: u32, height: u32, format: DepthFormat) -> Self {
        let n = width as usize * height as usize;
        match format {
            DepthFormat::None => Self::None,
            DepthFormat::D16 => Self::D16(vec![u16::MAX; n]),
            DepthFormat::D32 => Self::D32(vec![u32::MAX; n]),
        }
    }

    /// Values held: `pixels` for no depth buffer, which fits a surface of any size.
    pub fn len_for(&self, pixels: usize) -> usize {
        match self {
            Self::None => pixels,
            Self::D16(d) => d.len(),
            Self::D32(d) => d.len(),
        }
    }
}
