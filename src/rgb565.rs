//! RGB565 texels and mipmap chains (2 x 2 box filter, computed in 8-bit RGB).

/// Packs 8-bit RGB into RGB565 (rounded).
pub fn pack(rgb: [u8; 3]) -> u16 {
    let r = (u16::from(rgb[0]) * 31 + 127) / 255;
    let g = (u16::from(rgb[1]) * 63 + 127) / 255;
    let b = (u16::from(rgb[2]) * 31 + 127) / 255;
    (r << 11) | (g << 5) | b
}

/// Unpacks RGB565 into 8-bit RGB (bit replication).
pub fn unpack(t: u16) -> [u8; 3] {
    let r = ((t >> 11) & 31) as u8;
    let g = ((t >> 5) & 63) as u8;
    let b = (t & 31) as u8;
    [
        (r << 3) | (r >> 2),
        (g << 2) | (g >> 4),
        (b << 3) | (b >> 2),
    ]
}

/// The number of mip levels of a square power-of-two texture of side `size` (down to 1 x 1).
pub fn mip_count(size: usize) -> usize {
    size.max(1).ilog2() as usize + 1
}

/// The total texels of a full mip chain of side `size`.
pub fn mip_chain_texels(size: usize) -> usize {
    (0..mip_count(size)).map(|l| (size >> l).pow(2)).sum()
}

/// The RGB565 mip chain of a square power-of-two RGB texture of side `size`, finest first,
/// down to 1 x 1, each level a 2 x 2 box filter of the previous one.
pub fn mip_chain(rgb: &[[u8; 3]], size: usize) -> Vec<Vec<u16>> {
    debug_assert!(size.is_power_of_two() && rgb.len() == size * size);
    let mut levels = vec![rgb.iter().map(|&c| pack(c)).collect()];
    let mut current = rgb.to_vec();
    let mut side = size;
    while side > 1 {
        let half = side / 2;
        let mut next = Vec::with_capacity(half * half);
        for y in 0..half {
            for x in 0..half {
                let mut acc = [0u32; 3];
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let c = current[(2 * y + dy) * side + 2 * x + dx];
                    for k in 0..3 {
                        acc[k] += u32::from(c[k]);
                    }
                }
                next.push(acc.map(|a| ((a + 2) / 4) as u8));
            }
        }
        levels.push(next.iter().map(|&c| pack(c)).collect());
        current = next;
        side = half;
    }
    levels
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pack_unpack_keeps_extremes_and_chain_reaches_one_texel() {
        assert_eq!(unpack(pack([255, 255, 255])), [255, 255, 255]);
        assert_eq!(unpack(pack([0, 0, 0])), [0, 0, 0]);
        let chain = mip_chain(&[[255, 0, 0], [0, 0, 255], [255, 0, 0], [0, 0, 255]], 2);
        assert_eq!(chain.len(), 2);
        assert_eq!(unpack(chain[1][0]), [132, 0, 132]);
        assert_eq!(mip_count(128), 8);
        assert_eq!(mip_chain_texels(4), 21);
    }
}
