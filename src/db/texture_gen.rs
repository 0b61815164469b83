//! Tile textures: computed from the heights (colour ramp + hill shading), or cut from a colour
//! image that covers the whole DEM.
//!
//! Texel `(u, v)` of a tile texture of side `t` shows the point
//! `(x0 + u (s - 1) / (t - 1), y0 + v (s - 1) / (t - 1))` in sample units, where `(x0, y0)` is
//! the tile's first sample: the edge texels lie on the tile's borders, and the texel on a border
//! is the same in both tiles that share it (see [`crate::db::tile::texture_coordinate`], which
//! maps a vertex to the centre of that texel). A computed texel is the bilinear height of the
//! cell the point lies in, shaded by the bilinear blend of the gradients at the cell's corners,
//! central differences that read the neighbouring tiles' samples at a border, so both tiles
//! compute a border texel alike and the shading has no step at cell or tile edges.

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

/// Where texel `u` of a `texture_size` texture lies across a tile of `s` samples: the cell
/// (counted from the tile's first sample; `s - 1` is the cell beyond the last border) and the
/// fraction `0 <= f < 1` across it.
fn texel_point(u: usize, s: usize, texture_size: usize) -> (usize, f32) {
    let (along, span) = (u * (s - 1), texture_size.max(2) - 1);
    (along / span, (along % span) as f32 / span as f32)
}

/// The hill-shaded ramp texture of one tile of `s x s` samples, `spacing` metres apart,
/// `factor` texels per cell: `((s - 1) * factor)^2` RGB texels. `height(x, y)` is the height in
/// metres of the sample `(x, y)` from the tile's first sample, for `x, y` in `-1 ..= s`, `None`
/// beyond the grid. A texel's colour is the ramp at its bilinear height, shaded by the bilinear
/// blend of its cell's corner gradients, each a central difference (one-sided only at the
/// grid's edges): on a border both tiles blend the same corners with the same weights.
pub fn shaded(
    s: usize,
    spacing: f32,
    factor: usize,
    height: impl Fn(isize, isize) -> Option<f32>,
) -> Vec<[u8; 3]> {
    let size = (s - 1) * factor;
    let h = |i: usize, j: usize| {
        height(i as isize, j as isize).expect("every sample of the tile is given")
    };
    // The slope at sample (i, j) along (di, dj), metres per metre.
    let slope = |i: usize, j: usize, di: isize, dj: isize| {
        let (x, y) = (i as isize, j as isize);
        let here = h(i, j);
        match (height(x + di, y + dj), height(x - di, y - dj)) {
            (Some(a), Some(b)) => (a - b) / (2.0 * spacing),
            (Some(a), None) => (a - here) / spacing,
            (None, Some(b)) => (here - b) / spacing,
            (None, None) => 0.0,
        }
    };
    let corners: Vec<[f32; 3]> = (0..s * s)
        .map(|k| {
            let (i, j) = (k % s, k / s);
            [h(i, j), slope(i, j, 1, 0), slope(i, j, 0, 1)]
        })
        .collect();
    // Exact at both ends: a point on a border gets its border sample's values alone.
    let lerp = |a: f32, b: f32, f: f32| a * (1.0 - f) + b * f;
    // The cell a point lies in, the last one for a point on the east or south border.
    let cell = |c: usize, f: f32| if c == s - 1 { (s - 2, 1.0) } else { (c, f) };
    let mut out = Vec::with_capacity(size * size);
    for v in 0..size {
        let (cj, fy) = texel_point(v, s, size);
        let (cj, fy) = cell(cj, fy);
        for u in 0..size {
            let (ci, fx) = texel_point(u, s, size);
            let (ci, fx) = cell(ci, fx);
            let at = |i: usize, j: usize| corners[j * s + i];
            let (c00, c10, c01, c11) = (
                at(ci, cj),
                at(ci + 1, cj),
                at(ci, cj + 1),
                at(ci + 1, cj + 1),
            );
            let [height, dx, dy]: [f32; 3] = std::array::from_fn(|k| {
                lerp(lerp(c00[k], c10[k], fx), lerp(c01[k], c11[k], fx), fy)
            });
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
        let point = |u: usize| {
            let (c, f) = texel_point(u, s, size);
            c as f32 + f
        };
        for v in 0..size {
            let y = (y0 + point(v) + 0.5) * sy - 0.5;
            let (yi, fy) = (y.max(0.0).floor() as usize, (y.max(0.0)).fract());
            for u in 0..size {
                let x = (x0 + point(u) + 0.5) * sx - 0.5;
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

    /// The heights of an `s x s` tile alone (nothing beyond it).
    fn alone(heights: &[f32], s: usize) -> impl Fn(isize, isize) -> Option<f32> + '_ {
        let s = s as isize;
        move |i, j| {
            ((0..s).contains(&i) && (0..s).contains(&j)).then(|| heights[(j * s + i) as usize])
        }
    }

    #[test]
    fn flat_land_is_lit_by_the_light_elevation_and_water_is_blue() {
        let t = shaded(3, 10.0, 1, alone(&[10.0; 9], 3));
        assert_eq!(t.len(), 4);
        assert!(t.iter().all(|&c| c == t[0]));
        assert_eq!(ramp(-1.0), WATER);
        let steep_away = shaded(2, 10.0, 1, alone(&[100.0, 0.0, 100.0, 0.0], 2));
        assert!(steep_away[0][1] < t[0][1]);
    }

    #[test]
    fn neighbours_hold_the_same_texels_on_their_shared_border() {
        // Two 9-sample tiles side by side on a 17 x 9 grid of rough heights, two texels a cell.
        let (w, s) = (17, 9);
        let grid: Vec<f32> = (0..w * s)
            .map(|k| 200.0 + 90.0 * ((k % w) as f32 * 0.7).sin() * ((k / w) as f32 * 0.4).cos())
            .collect();
        let tile = |x0: usize| {
            let grid = &grid;
            shaded(s, 10.0, 2, move |i, j| {
                let x = x0 as isize + i;
                ((0..w as isize).contains(&x) && (0..s as isize).contains(&j))
                    .then(|| grid[j as usize * w + x as usize])
            })
        };
        let (west, east) = (tile(0), tile(8));
        let t = (s - 1) * 2;
        for v in 0..t {
            assert_eq!(west[v * t + t - 1], east[v * t], "row {v}");
        }
        assert_ne!(west[t - 1], west[t - 2], "the relief shows");
    }
}
