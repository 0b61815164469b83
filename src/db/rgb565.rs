//! RGB565 mip chains of tile textures, sized for the archive: filtered so that every level's
//! edge texels stay on the tile's borders (the packing is the rasterizer's).

use stripmask_raster::rgb_to_rgb565;

/// The number of mip levels of a square power-of-two texture of side `size` (down to 1 x 1).
pub fn mip_count(size: usize) -> usize {
    size.max(1).ilog2() as usize + 1
}

/// The total texels of a full mip chain of side `size`.
pub fn mip_chain_texels(size: usize) -> usize {
    (0..mip_count(size)).map(|l| (size >> l).pow(2)).sum()
}

/// The RGB565 mip chain of a square power-of-two RGB tile texture of side `size`, finest first,
/// down to 1 x 1 (in 8-bit RGB, then packed). Each level's edge texels stay on the tile's
/// borders, as level 0's do: an edge texel is the mean of the two texels of the finer level's
/// edge along the border (a corner texel is the finer corner), every other texel the 2 x 2 box
/// of the finer level. The two tiles sharing a border hold the same texels along it at level 0,
/// so they do at every level, and a coarser mip shows no step at the border either.
pub fn mip_chain(rgb: &[[u8; 3]], size: usize) -> Vec<Vec<u16>> {
    debug_assert!(size.is_power_of_two() && rgb.len() == size * size);
    let mut chain = vec![rgb.to_vec()];
    let mut side = size;
    while side > 1 {
        let next = next_mip(chain.last().expect("level 0 is there"), side);
        chain.push(next);
        side /= 2;
    }
    chain
        .into_iter()
        .map(|level| level.into_iter().map(rgb_to_rgb565).collect())
        .collect()
}

/// The next mip (side `side / 2`) of one level of side `side` of a tile's chain, in 8-bit RGB,
/// filtered as [`mip_chain`] says: edge texels stay on the tile's borders.
pub fn next_mip(finer: &[[u8; 3]], side: usize) -> Vec<[u8; 3]> {
    let next = side / 2;
    // The finer texels along one axis that texel `x` of the next level averages.
    let span = |x: usize| match x {
        _ if next == 1 => 0..side,
        0 => 0..1,
        _ if x == next - 1 => side - 1..side,
        _ => 2 * x..2 * x + 2,
    };
    (0..next * next)
        .map(|k| {
            let (xs, ys) = (span(k % next), span(k / next));
            let n = (xs.len() * ys.len()) as u32;
            let mut sum = [0u32; 3];
            for y in ys {
                for c in &finer[y * side + xs.start..y * side + xs.end] {
                    (0..3).for_each(|i| sum[i] += u32::from(c[i]));
                }
            }
            sum.map(|s| ((s + n / 2) / n) as u8)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use stripmask_raster::rgb565_to_rgb;

    #[test]
    fn neighbours_hold_the_same_edge_texels_at_every_mip() {
        // Two 16-texel tiles side by side on a 31-texel-wide image: column 15 is the shared
        // border, held by both.
        let (w, t) = (31, 16);
        let image: Vec<[u8; 3]> = (0..w * t)
            .map(|k| {
                let (x, y) = (k % w, k / w);
                [
                    (x * 37 + y * 11) as u8,
                    (x * x + 3 * y) as u8,
                    ((y * 29) ^ x) as u8,
                ]
            })
            .collect();
        let tile = |x0: usize| {
            let texels: Vec<[u8; 3]> = (0..t * t)
                .map(|k| image[(k / t) * w + x0 + k % t])
                .collect();
            mip_chain(&texels, t)
        };
        let (west, east) = (tile(0), tile(15));
        for (level, (a, b)) in west.iter().zip(&east).enumerate().take(4) {
            let side = t >> level;
            for y in 0..side {
                assert_eq!(a[y * side + side - 1], b[y * side], "mip {level}, row {y}");
            }
        }
    }

    #[test]
    fn chain_reaches_one_texel_and_averages_in_8_bits() {
        let chain = mip_chain(&[[255, 0, 0], [0, 0, 255], [255, 0, 0], [0, 0, 255]], 2);
        assert_eq!(chain.len(), 2);
        assert_eq!(rgb565_to_rgb(chain[1][0]), [132, 0, 132]);
        assert_eq!(mip_count(128), 8);
        assert_eq!(mip_chain_texels(4), 21);
    }
}
