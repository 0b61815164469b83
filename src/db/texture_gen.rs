//! Tile textures: computed from the heights (colour ramp + hill shading), or cut from a colour
//! image that covers the whole DEM.
//!
//! Texel `(u, v)` of a tile texture of side `t` shows the point
//! `(x0 + u (s - 1) / (t - 1), y0 + v (s - 1) / (t - 1))` in sample units, where `(x0, y0)` is
//! the tile's first sample: the edge texels lie on the tile's borders, and the texel on a border
//! is the same in both tiles that share it (see [`crate::db::tile::texture_coordinate`], which
//! maps a vertex to the centre of that texel). A computed texel is the mean, over its
//! footprint, of a smooth shaded surface through the samples (see [`shaded`]), which reads the
//! neighbouring tiles' samples at a border, so both tiles compute a border texel alike and the
//! shading has no step at cell or tile edges.

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

/// The colour [`shaded`] gives flat ground at height `h` metres: what stands for a tile whose
/// samples are all nodata in the texture of the tiles above it.
pub fn flat(h: f32) -> [u8; 3] {
    let shade = AMBIENT + (1.0 - AMBIENT) * LIGHT[2];
    ramp(h).map(|c| (f32::from(c) * shade).round().min(255.0) as u8)
}

/// Where texel `u` of a `texture_size` texture lies across a tile of `s` samples: the cell
/// (counted from the tile's first sample; `s - 1` is the cell beyond the last border) and the
/// fraction `0 <= f < 1` across it.
fn texel_point(u: usize, s: usize, texture_size: usize) -> (usize, f32) {
    let (along, span) = (u * (s - 1), texture_size.max(2) - 1);
    (along / span, (along % span) as f32 / span as f32)
}

/// Points per texel along each axis at which [`shaded`] evaluates the shading: a texel is the
/// mean of `SUPERSAMPLE^2` points spread evenly over its footprint.
const SUPERSAMPLE: usize = 2;

/// Samples beyond a tile's borders that a texel's shading reads: the cubic around a point on the
/// border reads two samples out, and their gradients one more.
const REACH: isize = 3;

/// The Catmull-Rom weights of the four samples around a point at fraction `t` of the way from
/// the second to the third: a cubic through the samples, smooth across them.
fn catmull_rom(t: f32) -> [f32; 4] {
    let (t2, t3) = (t * t, t * t * t);
    [
        0.5 * (-t3 + 2.0 * t2 - t),
        0.5 * (3.0 * t3 - 5.0 * t2 + 2.0),
        0.5 * (-3.0 * t3 + 4.0 * t2 + t),
        0.5 * (t3 - t2),
    ]
}

/// Where point `k` of the `SUPERSAMPLE` spread across texel `u` of a `texture_size` texture lies
/// across a tile of `s` samples: the sample before it (counted from the tile's first sample,
/// `-1` for a point just outside the western border) and the fraction `0 <= f < 1` beyond it.
/// Exact: the same point seen from the two tiles sharing a border gets the same fraction.
fn footprint_point(u: usize, k: usize, s: usize, texture_size: usize) -> (isize, f32) {
    let n = SUPERSAMPLE as isize;
    // In units of 1 / (2 n span) samples, the texel's centre is at 2 n u (s - 1) and its
    // footprint spans one texel, (s - 1) / span samples, around it.
    let span = (texture_size.max(2) - 1) as isize;
    let unit = 2 * n * span;
    let along = (s as isize - 1) * (2 * n * u as isize + 2 * k as isize + 1 - n);
    (
        along.div_euclid(unit),
        along.rem_euclid(unit) as f32 / unit as f32,
    )
}

/// The hill-shaded ramp texture of one tile of `s x s` samples, `spacing` metres apart,
/// `factor` texels per cell: `((s - 1) * factor)^2` RGB texels. `height(x, y)` is the height in
/// metres of the sample `(x, y)` from the tile's first sample, for `x, y` in
/// `-3 ..= s + 2`, `None` beyond the grid.
///
/// The shading is a smooth surface through the samples: height and gradient (central
/// differences, one-sided only at the grid's edges) interpolated by Catmull-Rom cubics, a
/// point's colour the ramp at its height shaded by its gradient. A texel is the mean colour
/// over its footprint (`SUPERSAMPLE^2` points), so that its detail does not depend on where
/// it falls on the sample grid: texels lie on the samples only at the tile's borders (there are
/// `2^n` of them across `2^n` cells), and point samples of a surface interpolated between the
/// samples would be sharpest there, drawing a faint line along every border. The two tiles
/// sharing a border compute its texels from the same samples at the same points, alike.
pub fn shaded(
    s: usize,
    spacing: f32,
    factor: usize,
    height: impl Fn(isize, isize) -> Option<f32>,
) -> Vec<[u8; 3]> {
    let size = (s - 1) * factor;
    let last = s as isize - 1;
    // The grid's first and last column and row around this tile, in its sample coordinates:
    // the samples beyond are the grid's edge samples repeated.
    let extent = |present: &dyn Fn(isize) -> bool| {
        let first = (-REACH..=0).find(|&k| present(k)).unwrap_or(0);
        let end = (last..=last + REACH)
            .rev()
            .find(|&k| present(k))
            .unwrap_or(last);
        (first, end)
    };
    let (x0, x1) = extent(&|x| height(x, 0).is_some());
    let (y0, y1) = extent(&|y| height(0, y).is_some());
    let h = |x: isize, y: isize| {
        height(x.clamp(x0, x1), y.clamp(y0, y1)).expect("every sample of the grid is given")
    };
    // The slope at `at` along one axis whose samples `sample` gives, metres per metre: central,
    // one-sided at the grid's edges `first` and `end`.
    let slope = |at: isize, first: isize, end: isize, sample: &dyn Fn(isize) -> f32| match (
        at > first,
        at < end,
    ) {
        (true, true) => (sample(at + 1) - sample(at - 1)) / (2.0 * spacing),
        (false, true) => (sample(at + 1) - sample(at)) / spacing,
        (true, false) => (sample(at) - sample(at - 1)) / spacing,
        (false, false) => 0.0,
    };
    // Height and gradient at every sample from `1 - REACH` to `last + REACH - 1`, the grid's
    // edge samples standing in beyond it.
    let reach = REACH - 1;
    let side = s + 2 * reach as usize;
    let corners: Vec<[f32; 3]> = (0..side * side)
        .map(|k| {
            let (x, y) = (
                ((k % side) as isize - reach).clamp(x0, x1),
                ((k / side) as isize - reach).clamp(y0, y1),
            );
            [
                h(x, y),
                slope(x, x0, x1, &|i| h(i, y)),
                slope(y, y0, y1, &|j| h(x, j)),
            ]
        })
        .collect();
    let at = |x: isize, y: isize| corners[((y + reach) * side as isize + x + reach) as usize];
    let points = (SUPERSAMPLE * SUPERSAMPLE) as f32;
    let mut out = Vec::with_capacity(size * size);
    for v in 0..size {
        for u in 0..size {
            let mut sum = [0f32; 3];
            for ky in 0..SUPERSAMPLE {
                let (cy, fy) = footprint_point(v, ky, s, size);
                let wy = catmull_rom(fy);
                for kx in 0..SUPERSAMPLE {
                    let (cx, fx) = footprint_point(u, kx, s, size);
                    let wx = catmull_rom(fx);
                    let mut value = [0f32; 3];
                    for (j, wj) in wy.iter().enumerate() {
                        for (i, wi) in wx.iter().enumerate() {
                            let c = at(cx + i as isize - 1, cy + j as isize - 1);
                            (0..3).for_each(|m| value[m] += wi * wj * c[m]);
                        }
                    }
                    let [height, dx, dy] = value;
                    let n = [-dx, -dy, 1.0];
                    let len = (n[0] * n[0] + n[1] * n[1] + 1.0).sqrt();
                    let lambert =
                        ((n[0] * LIGHT[0] + n[1] * LIGHT[1] + n[2] * LIGHT[2]) / len).max(0.0);
                    let shade = AMBIENT + (1.0 - AMBIENT) * lambert;
                    let base = ramp(height);
                    (0..3).for_each(|m| sum[m] += f32::from(base[m]) * shade);
                }
            }
            out.push(sum.map(|c| (c / points).round().min(255.0) as u8));
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
