//! Tile textures: computed from the heights (colour ramp + hill shading), or cut from a colour
//! image that covers the whole DEM.
//!
//! Texel `(u, v)` of a tile texture with `f` texels per cell covers the point
//! `(x0 + (u + 0.5) / f, y0 + (v + 0.5) / f)` in sample units, where `(x0, y0)` is the tile's first
//! sample. A computed texel uses only the four samples of its cell (bilinear height, the cell's
//! gradient for the normal), so textures of neighbouring tiles meet without seams.

use std::path::Path;

use crate::error::{Error, Result};

/// Colour stops of the height ramp: (metres, RGB). Heights at or below 0 are water.
const RAMP: [(f32, [u8; 3]); 7] = [
    (0.0, [70, 120, 60]),
    (150.0, [95, 140, 70]),
    (500.0, [140, 150, 85]),
    (1000.0, [150, 125, 90]),
    (1600.0, [130, 110, 100]),
    (2200.0, [190, 190, 190]),
    (3000.0, [250, 250, 250]),
];
const WATER: [u8; 3] = [60, 95, 150];

/// Direction to the light (from the north-west, 45 degrees up), normalised; x east, y south, z up.
const LIGHT: [f32; 3] = [-0.5, -0.5, std::f32::consts::FRAC_1_SQRT_2];
const AMBIENT: f32 = 0.35;

/// The ramp colour of a height in metres.
pub fn ramp(h: f32) -> [u8; 3] {
    if h <= 0.0 {
        return WATER;
    }
    for w in RAMP.windows(2) {
        let ((h0, c0), (h1, c1)) = (w[0], w[1]);
        if h <= h1 {
            let t = ((h - h0) / (h1 - h0)).clamp(0.0, 1.0);
            return std::array::from_fn(|k| {
                (f32::from(c0[k]) + t * (f32::from(c1[k]) - f32::from(c0[k]))).round() as u8
            });
        }
    }
    RAMP[RAMP.len() - 1].1
}

/// The hill-shaded ramp texture of one tile: `heights` are `s x s` metres, `spacing` metres
/// between samples, `factor` texels per cell; returns `((s - 1) * factor)^2` RGB texels.
pub fn shaded(heights: &[f32], s: usize, spacing: f32, factor: usize) -> Vec<[u8; 3]> {
    let size = (s - 1) * factor;
    let mut out = Vec::with_capacity(size * size);
    let h = |i: usize, j: usize| heights[j * s + i];
    for v in 0..size {
        let (cj, fy) = (v / factor, ((v % factor) as f32 + 0.5) / factor as f32);
        for u in 0..size {
            let (ci, fx) = (u / factor, ((u % factor) as f32 + 0.5) / factor as f32);
            let (h00, h10) = (h(ci, cj), h(ci + 1, cj));
            let (h01, h11) = (h(ci, cj + 1), h(ci + 1, cj + 1));
            let top = h00 + fx * (h10 - h00);
            let bottom = h01 + fx * (h11 - h01);
            let height = top + fy * (bottom - top);
            let dx = ((h10 - h00) + (h11 - h01)) / (2.0 * spacing);
            let dy = ((h01 - h00) + (h11 - h10)) / (2.0 * spacing);
            let n = [-dx, -dy, 1.0];
            let len = (n[0] * n[0] + n[1] * n[1] + 1.0).sqrt();
            let lambert = ((n[0] * LIGHT[0] + n[1] * LIGHT[1] + n[2] * LIGHT[2]) / len).max(0.0);
            let shade = AMBIENT + (1.0 - AMBIENT) * lambert;
            let base = ramp(height);
            out.push(base.map(|c| (f32::from(c) * shade).round().min(255.0) as u8));
        }
    }
    out
}

/// A colour image that covers the whole DEM, cut into tile textures.
///
/// The image's pixels are areas aligned with the DEM's samples: pixel edges `0 ..= width` span
/// sample coordinates `-0.5 ..= dem_width - 0.5` (as when the image and the DEM share a raster).
/// The whole image is held in memory as 8-bit RGB.
pub struct ImageTexture {
    image: image::RgbImage,
    dem_width: usize,
    dem_height: usize,
}

impl ImageTexture {
    /// Loads `path` for a DEM of `dem_width x dem_height` samples.
    pub fn open(path: &Path, dem_width: usize, dem_height: usize) -> Result<Self> {
        let image = image::open(path)
            .map_err(|e| {
                Error::invalid(
                    path.display().to_string(),
                    format!("cannot read the texture image: {e}"),
                )
            })?
            .to_rgb8();
        Ok(ImageTexture {
            image,
            dem_width,
            dem_height,
        })
    }

    /// The texture of tile `(tx, ty)`: `((s - 1) * factor)^2` texels, bilinear from the image.
    pub fn cut(&self, tx: usize, ty: usize, s: usize, factor: usize) -> Vec<[u8; 3]> {
        let size = (s - 1) * factor;
        let (iw, ih) = (self.image.width() as usize, self.image.height() as usize);
        let sx = iw as f32 / self.dem_width as f32;
        let sy = ih as f32 / self.dem_height as f32;
        let x0 = (tx * (s - 1)) as f32;
        let y0 = (ty * (s - 1)) as f32;
        let mut out = Vec::with_capacity(size * size);
        let px = |x: usize, y: usize| {
            self.image
                .get_pixel(x.min(iw - 1) as u32, y.min(ih - 1) as u32)
                .0
        };
        for v in 0..size {
            let y = (y0 + (v as f32 + 0.5) / factor as f32 + 0.5) * sy - 0.5;
            let (yi, fy) = (y.max(0.0).floor() as usize, (y.max(0.0)).fract());
            for u in 0..size {
                let x = (x0 + (u as f32 + 0.5) / factor as f32 + 0.5) * sx - 0.5;
                let (xi, fx) = (x.max(0.0).floor() as usize, (x.max(0.0)).fract());
                let (a, b, c, d) = (
                    px(xi, yi),
                    px(xi + 1, yi),
                    px(xi, yi + 1),
                    px(xi + 1, yi + 1),
                );
                out.push(std::array::from_fn(|k| {
                    let top = f32::from(a[k]) + fx * (f32::from(b[k]) - f32::from(a[k]));
                    let bottom = f32::from(c[k]) + fx * (f32::from(d[k]) - f32::from(c[k]));
                    (top + fy * (bottom - top)).round() as u8
                }));
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flat_land_is_lit_by_the_light_elevation_and_water_is_blue() {
        let t = shaded(&[10.0; 9], 3, 10.0, 1);
        assert_eq!(t.len(), 4);
        assert!(t.iter().all(|&c| c == t[0]));
        assert_eq!(ramp(-1.0), WATER);
        let steep_away = shaded(&[100.0, 0.0, 100.0, 0.0], 2, 10.0, 1);
        assert!(steep_away[0][1] < t[0][1]);
    }
}
