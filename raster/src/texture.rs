//! Textures in the handheld's RGB565 or in RGBA8888, with mip chains.
//!
//! Sides are powers of two (as OpenGL ES 1.x required), so wrapping is a mask and a texel address a
//! shift.

use image::RgbaImage;

use crate::RasterError;
use crate::pixel::{rgb_to_rgb565, rgb565_to_rgb};

/// Storage format of a texture.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TextureFormat {
    /// 16 bits per texel, 5-6-5: half the memory and bandwidth of RGBA8888.
    Rgb565,
    /// 32 bits per texel (alpha is stored but not used).
    Rgba8888,
}

/// Texels of one mip level.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Texels {
    /// Packed 5-6-5.
    Rgb565(Vec<u16>),
    /// Bytes in R, G, B, A order.
    Rgba8888(Vec<[u8; 4]>),
}

/// One level of a mip chain.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MipLevel {
    width: u32,
    height: u32,
    texels: Texels,
}

impl MipLevel {
    /// Width in texels.
    pub fn width(&self) -> u32 {
        self.width
    }
    /// Height in texels.
    pub fn height(&self) -> u32 {
        self.height
    }
    /// The texels, row-major.
    pub fn texels(&self) -> &Texels {
        &self.texels
    }

    fn new(width: u32, height: u32, texels: Texels) -> Result<Self, RasterError> {
        if !width.is_power_of_two()
            || !height.is_power_of_two()
            || width > 1 << 15
            || height > 1 << 15
        {
            return Err(RasterError::TextureSize { width, height });
        }
        let len = match &texels {
            Texels::Rgb565(t) => t.len(),
            Texels::Rgba8888(t) => t.len(),
        };
        if len != width as usize * height as usize {
            return Err(RasterError::TextureData {
                expected: width as usize * height as usize,
                got: len,
            });
        }
        Ok(Self {
            width,
            height,
            texels,
        })
    }
}

/// The mip chain of an 8-bit RGB image with power-of-two sides, finest first, down to 1x1: each
/// level a 2x2 box filter of the one before (a side already 1 stays 1), computed in 8 bits
/// throughout so that packing to RGB565 rounds once per level, not once per step.
pub fn box_mip_chain(
    width: u32,
    height: u32,
    level0: Vec<[u8; 3]>,
) -> Vec<(u32, u32, Vec<[u8; 3]>)> {
    debug_assert_eq!(level0.len(), width as usize * height as usize);
    let mut chain = vec![(width, height, level0)];
    while let Some((w, h, src)) = chain.last().filter(|(w, h, _)| *w > 1 || *h > 1) {
        let (nw, nh) = ((w / 2).max(1), (h / 2).max(1));
        let (sx, sy, sw) = ((w / nw) as usize, (h / nh) as usize, *w as usize);
        let n = (sx * sy) as u32;
        let mut next = Vec::with_capacity(nw as usize * nh as usize);
        for y in 0..nh as usize {
            for x in 0..nw as usize {
                let mut sum = [0u32; 3];
                for dy in 0..sy {
                    for dx in 0..sx {
                        let c = src[(y * sy + dy) * sw + x * sx + dx];
                        (0..3).for_each(|k| sum[k] += c[k] as u32);
                    }
                }
                next.push(sum.map(|s| ((s + n / 2) / n) as u8));
            }
        }
        chain.push((nw, nh, next));
    }
    chain
}

/// A texture: level 0 and, optionally, its coarser levels down to 1x1.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Texture {
    levels: Vec<MipLevel>,
}

impl Texture {
    /// A single-level RGB565 texture.
    pub fn from_rgb565(width: u32, height: u32, texels: Vec<u16>) -> Result<Self, RasterError> {
        Ok(Self {
            levels: vec![MipLevel::new(width, height, Texels::Rgb565(texels))?],
        })
    }

    /// A single-level RGBA8888 texture.
    pub fn from_rgba8(width: u32, height: u32, texels: Vec<[u8; 4]>) -> Result<Self, RasterError> {
        Ok(Self {
            levels: vec![MipLevel::new(width, height, Texels::Rgba8888(texels))?],
        })
    }

    /// A single-level texture from an image, converted to `format`.
    pub fn from_image(image: &RgbaImage, format: TextureFormat) -> Result<Self, RasterError> {
        let (w, h) = image.dimensions();
        let px = image.pixels().map(|p| p.0);
        match format {
            TextureFormat::Rgb565 => Self::from_rgb565(
                w,
                h,
                px.map(|p| rgb_to_rgb565([p[0], p[1], p[2]])).collect(),
            ),
            TextureFormat::Rgba8888 => Self::from_rgba8(w, h, px.collect()),
        }
    }

    /// A texture from a complete chain that was stored elsewhere (e.g. an archive). Each level must
    /// halve the one before, down to 1x1, in one format.
    pub fn from_levels(levels: Vec<(u32, u32, Texels)>) -> Result<Self, RasterError> {
        let levels = levels
            .into_iter()
            .map(|(w, h, t)| MipLevel::new(w, h, t))
            .collect::<Result<Vec<_>, _>>()?;
        let Some(first) = levels.first() else {
            return Err(RasterError::TextureData {
                expected: 1,
                got: 0,
            });
        };
        let same_format = |l: &MipLevel| {
            std::mem::discriminant(&l.texels) == std::mem::discriminant(&first.texels)
        };
        let halves = levels.windows(2).all(|p| {
            p[1].width == (p[0].width / 2).max(1) && p[1].height == (p[0].height / 2).max(1)
        });
        let last = levels.last().expect("non-empty");
        if !levels.iter().all(same_format)
            || !halves
            || (levels.len() > 1 && (last.width, last.height) != (1, 1))
        {
            return Err(RasterError::MipChain);
        }
        Ok(Self { levels })
    }

    /// Builds the mip chain down to 1x1 with a 2x2 box filter (replacing any coarser levels).
    pub fn with_mipmaps(mut self) -> Self {
        self.levels.truncate(1);
        let base = &self.levels[0];
        let rgb: Vec<[u8; 3]> = match &base.texels {
            Texels::Rgb565(t) => t.iter().map(|&p| rgb565_to_rgb(p)).collect(),
            Texels::Rgba8888(t) => t.iter().map(|p| [p[0], p[1], p[2]]).collect(),
        };
        let chain = box_mip_chain(base.width, base.height, rgb);
        let rgb565 = matches!(base.texels, Texels::Rgb565(_));
        for (width, height, level) in chain.into_iter().skip(1) {
            let texels = if rgb565 {
                Texels::Rgb565(level.into_iter().map(rgb_to_rgb565).collect())
            } else {
                Texels::Rgba8888(level.into_iter().map(|[r, g, b]| [r, g, b, 255]).collect())
            };
            self.levels.push(MipLevel {
                width,
                height,
                texels,
            });
        }
        self
    }

    /// The levels, finest first.
    pub fn levels(&self) -> &[MipLevel] {
        &self.levels
    }

    /// Storage format.
    pub fn format(&self) -> TextureFormat {
        match self.levels[0].texels {
            Texels::Rgb565(_) => TextureFormat::Rgb565,
            Texels::Rgba8888(_) => TextureFormat::Rgba8888,
        }
    }

    /// Bytes held by all levels, for memory accounting.
    pub fn byte_size(&self) -> usize {
        let per_texel = match self.format() {
            TextureFormat::Rgb565 => 2,
            TextureFormat::Rgba8888 => 4,
        };
        self.levels
            .iter()
            .map(|l| l.width as usize * l.height as usize * per_texel)
            .sum()
    }

    /// Mip level for a triangle whose texture-space area, in level-0 texels squared, is
    /// `2^texel_area_log2` times its screen area in pixels: the level whose texels are about one
    /// pixel across. Per triangle, not per pixel: cheap, and terrain triangles are small.
    pub(crate) fn level_for_area_ratio(&self, texel_per_pixel_area_log2: i32) -> usize {
        (texel_per_pixel_area_log2.max(0) as usize / 2).min(self.levels.len() - 1)
    }
}

/// Minification/magnification filter.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Filter {
    /// The texel under the sample point.
    Nearest,
    /// Weighted average of the four texels around it (8-bit weights).
    Bilinear,
}

/// Mip level choice.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MipFilter {
    /// Always level 0.
    None,
    /// The level whose texel size best matches the triangle's pixel size.
    Nearest,
}

/// Behaviour outside `0..1`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Wrap {
    /// Clamp to the edge texel.
    Clamp,
    /// Tile the texture.
    Repeat,
}

/// How a texture is read.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Sampler {
    /// Texel filter.
    pub filter: Filter,
    /// Mip level selection.
    pub mip: MipFilter,
    /// Wrap mode (both axes).
    pub wrap: Wrap,
}

impl Sampler {
    /// Nearest texel of level 0, clamped.
    pub const NEAREST: Self = Self {
        filter: Filter::Nearest,
        mip: MipFilter::None,
        wrap: Wrap::Clamp,
    };
    /// Bilinear on level 0, clamped.
    pub const BILINEAR: Self = Self {
        filter: Filter::Bilinear,
        mip: MipFilter::None,
        wrap: Wrap::Clamp,
    };
    /// Bilinear on the level chosen per triangle, clamped: the terrain default.
    pub const BILINEAR_MIPMAP: Self = Self {
        filter: Filter::Bilinear,
        mip: MipFilter::Nearest,
        wrap: Wrap::Clamp,
    };
}

impl Default for Sampler {
    fn default() -> Self {
        Self::BILINEAR_MIPMAP
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn non_power_of_two_and_short_data_are_refused() {
        assert!(matches!(
            Texture::from_rgb565(3, 4, vec![0; 12]),
            Err(RasterError::TextureSize { .. })
        ));
        assert!(matches!(
            Texture::from_rgb565(4, 4, vec![0; 15]),
            Err(RasterError::TextureData { .. })
        ));
    }

    #[test]
    fn mip_chain_halves_down_to_one_texel_and_averages() {
        let mut t = vec![[0u8, 0, 0, 255]; 8 * 2];
        for (i, p) in t.iter_mut().enumerate() {
            if i % 2 == 0 {
                *p = [200, 100, 50, 255];
            }
        }
        let tex = Texture::from_rgba8(8, 2, t).unwrap().with_mipmaps();
        let sizes: Vec<_> = tex
            .levels()
            .iter()
            .map(|l| (l.width(), l.height()))
            .collect();
        assert_eq!(sizes, vec![(8, 2), (4, 1), (2, 1), (1, 1)]);
        let Texels::Rgba8888(l1) = tex.levels()[1].texels() else {
            panic!()
        };
        assert!(l1.iter().all(|p| *p == [100, 50, 25, 255]));
        assert_eq!(tex.byte_size(), (16 + 4 + 2 + 1) * 4);
    }

    #[test]
    fn stored_chains_are_checked() {
        let ok = Texture::from_levels(vec![
            (2, 2, Texels::Rgb565(vec![0; 4])),
            (1, 1, Texels::Rgb565(vec![0; 1])),
        ]);
        assert!(ok.is_ok());
        let bad = Texture::from_levels(vec![
            (4, 4, Texels::Rgb565(vec![0; 16])),
            (1, 1, Texels::Rgb565(vec![0])),
        ]);
        assert!(matches!(bad, Err(RasterError::MipChain)));
    }

    #[test]
    fn level_choice_follows_the_area_ratio() {
        let tex = Texture::from_rgb565(16, 16, vec![0; 256])
            .unwrap()
            .with_mipmaps();
        assert_eq!(tex.level_for_area_ratio(-3), 0);
        assert_eq!(tex.level_for_area_ratio(1), 0);
        assert_eq!(tex.level_for_area_ratio(2), 1);
        assert_eq!(tex.level_for_area_ratio(5), 2);
        assert_eq!(tex.level_for_area_ratio(40), 4);
    }
}
