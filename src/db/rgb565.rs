//! RGB565 mip chains of tile textures, sized for the archive (the box filter and the packing are
//! the rasterizer's, so a texture built here is the one the renderer would build itself).

use stripmask_raster::{box_mip_chain, rgb_to_rgb565};

/// The number of mip levels of a square power-of-two texture of side `size` (down to 1 x 1).
pub fn mip_count(size: usize) -> usize {
    size.max(1).ilog2() as usize + 1
}

/// The total texels of a full mip chain of side `size`.
pub fn mip_chain_texels(size: usize) -> usize {
    (0..mip_count(size)).map(|l| (size >> l).pow(2)).sum()
}

/// The RGB565 mip chain of a square power-of-two RGB texture of side `size`, finest first,
/// down to 1 x 1, each level a 2 x 2 box filter of the previous one (in 8-bit RGB).
pub fn mip_chain(rgb: &[[u8; 3]], size: usize) -> Vec<Vec<u16>> {
    debug_assert!(size.is_power_of_two() && rgb.len() == size * size);
    box_mip_chain(size as u32, size as u32, rgb.to_vec())
        .into_iter()
        .map(|(_, _, level)| level.into_iter().map(rgb_to_rgb565).collect())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use stripmask_raster::rgb565_to_rgb;

    #[test]
    fn chain_reaches_one_texel_and_averages_in_8_bits() {
        let chain = mip_chain(&[[255, 0, 0], [0, 0, 255], [255, 0, 0], [0, 0, 255]], 2);
        assert_eq!(chain.len(), 2);
        assert_eq!(rgb565_to_rgb(chain[1][0]), [132, 0, 132]);
        assert_eq!(mip_count(128), 8);
        assert_eq!(mip_chain_texels(4), 21);
    }
}
