//! Image error against a reference: PSNR, SSIM, and pixels off by more than a threshold.
//!
//! SSIM is the standard one of Wang, Bovik, Sheikh and Simoncelli (2004), as their reference
//! MATLAB code computes it: on luma (BT.601 weights), an 11 x 11 Gaussian window with σ = 1.5,
//! `K1 = 0.01`, `K2 = 0.03`, `L = 255`, averaged over the window positions inside the image.
//! It is written here because the Rust crates that offer SSIM either use another definition
//! (image-compare: 8 x 8 boxes, per channel) or an incompatible licence (dssim: AGPL).

use image::RgbaImage;

/// How far one image is from a reference.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ImageError {
    /// Mean squared error over the R, G and B values (0..=255 each).
    pub mse: f64,
    /// Mean SSIM over the window positions, 1 for identical images.
    pub ssim: f64,
    /// Pixels where some channel differs by more than the threshold.
    pub pixels_off: u64,
    /// Pixels compared.
    pub pixels: u64,
}

/// PSNR in dB of a mean squared error over 8-bit values (infinite for identical images).
pub fn psnr(mse: f64) -> f64 {
    if mse <= 0.0 {
        f64::INFINITY
    } else {
        10.0 * (255.0 * 255.0 / mse).log10()
    }
}

/// Compares `image` with `reference` (same size): MSE, SSIM, and the pixels where a channel
/// differs by more than `threshold`.
pub fn compare(image: &RgbaImage, reference: &RgbaImage, threshold: u8) -> ImageError {
    assert_eq!(
        image.dimensions(),
        reference.dimensions(),
        "images of one size"
    );
    let mut squared = 0u64;
    let mut pixels_off = 0;
    for (a, b) in image.pixels().zip(reference.pixels()) {
        let mut worst = 0;
        for c in 0..3 {
            let d = a.0[c].abs_diff(b.0[c]);
            squared += u64::from(d) * u64::from(d);
            worst = worst.max(d);
        }
        pixels_off += u64::from(worst > threshold);
    }
    let pixels = u64::from(image.width()) * u64::from(image.height());
    ImageError {
        mse: squared as f64 / (3 * pixels).max(1) as f64,
        ssim: ssim(&luma(image), &luma(reference), image.width() as usize),
        pixels_off,
        pixels,
    }
}

/// BT.601 luma of every pixel, row-major, 0..=255.
fn luma(image: &RgbaImage) -> Vec<f64> {
    image
        .pixels()
        .map(|p| 0.299 * f64::from(p.0[0]) + 0.587 * f64::from(p.0[1]) + 0.114 * f64::from(p.0[2]))
        .collect()
}

/// Side of the Gaussian window.
const WINDOW: usize = 11;
/// Its standard deviation, pixels.
const SIGMA: f64 = 1.5;
const C1: f64 = (0.01 * 255.0) * (0.01 * 255.0);
const C2: f64 = (0.03 * 255.0) * (0.03 * 255.0);

/// Mean SSIM of two luma planes `width` wide. Images smaller than the window in either
/// direction are one window of equal weights.
pub fn ssim(x: &[f64], y: &[f64], width: usize) -> f64 {
    debug_assert_eq!(x.len(), y.len());
    let height = x.len() / width.max(1);
    if width < WINDOW || height < WINDOW {
        return ssim_of(&moments(x, y, &vec![1.0 / x.len().max(1) as f64; x.len()]));
    }
    let kernel = gaussian();
    // Separable filtering of the five planes x, y, x², y², xy ("valid" region only).
    let planes: [Vec<f64>; 5] = [
        x.to_vec(),
        y.to_vec(),
        x.iter().map(|v| v * v).collect(),
        y.iter().map(|v| v * v).collect(),
        x.iter().zip(y).map(|(a, b)| a * b).collect(),
    ];
    let (ow, oh) = (width - WINDOW + 1, height - WINDOW + 1);
    let filtered: Vec<Vec<f64>> = planes
        .iter()
        .map(|p| {
            let rows: Vec<f64> = (0..height)
                .flat_map(|j| {
                    let row = &p[j * width..(j + 1) * width];
                    (0..ow).map(move |i| dot(&row[i..i + WINDOW], &kernel))
                })
                .collect();
            (0..oh)
                .flat_map(|j| {
                    let rows = &rows;
                    let kernel = &kernel;
                    (0..ow).map(move |i| {
                        (0..WINDOW)
                            .map(|k| rows[(j + k) * ow + i] * kernel[k])
                            .sum()
                    })
                })
                .collect()
        })
        .collect();
    let total: f64 = (0..ow * oh)
        .map(|k| {
            let (mx, my) = (filtered[0][k], filtered[1][k]);
            ssim_of(&Moments {
                mx,
                my,
                vx: filtered[2][k] - mx * mx,
                vy: filtered[3][k] - my * my,
                cov: filtered[4][k] - mx * my,
            })
        })
        .sum();
    total / (ow * oh) as f64
}

/// Weighted means, variances and covariance of a window.
struct Moments {
    mx: f64,
    my: f64,
    vx: f64,
    vy: f64,
    cov: f64,
}

fn moments(x: &[f64], y: &[f64], w: &[f64]) -> Moments {
    let mx = dot(x, w);
    let my = dot(y, w);
    let m = |f: &dyn Fn(usize) -> f64| (0..x.len()).map(|k| w[k] * f(k)).sum::<f64>();
    Moments {
        mx,
        my,
        vx: m(&|k| (x[k] - mx) * (x[k] - mx)),
        vy: m(&|k| (y[k] - my) * (y[k] - my)),
        cov: m(&|k| (x[k] - mx) * (y[k] - my)),
    }
}

fn ssim_of(m: &Moments) -> f64 {
    ((2.0 * m.mx * m.my + C1) * (2.0 * m.cov + C2))
        / ((m.mx * m.mx + m.my * m.my + C1) * (m.vx + m.vy + C2))
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(p, q)| p * q).sum()
}

/// The normalised 1-D Gaussian of the window (the 2-D window is its outer product).
fn gaussian() -> [f64; WINDOW] {
    let c = (WINDOW / 2) as f64;
    let mut k = [0.0; WINDOW];
    for (i, v) in k.iter_mut().enumerate() {
        let d = i as f64 - c;
        *v = (-d * d / (2.0 * SIGMA * SIGMA)).exp();
    }
    let sum: f64 = k.iter().sum();
    k.map(|v| v / sum)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plane(w: usize, h: usize, f: impl Fn(usize, usize) -> f64) -> Vec<f64> {
        (0..w * h).map(|k| f(k % w, k / w)).collect()
    }

    #[test]
    fn identical_images_have_ssim_one_and_infinite_psnr() {
        let x = plane(40, 30, |i, j| ((i * 7 + j * 13) % 256) as f64);
        assert!((ssim(&x, &x, 40) - 1.0).abs() < 1e-12);
        assert_eq!(psnr(0.0), f64::INFINITY);
    }

    #[test]
    fn flat_images_reduce_to_the_luminance_term() {
        // No variance anywhere: SSIM = (2ab + C1) / (a² + b² + C1), at any size.
        let (a, b) = (100.0, 110.0);
        let expected = (2.0 * a * b + C1) / (a * a + b * b + C1);
        for (w, h) in [(32, 24), (5, 3)] {
            let got = ssim(&plane(w, h, |_, _| a), &plane(w, h, |_, _| b), w);
            assert!(
                (got - expected).abs() < 1e-12,
                "{w}x{h}: {got} vs {expected}"
            );
        }
        assert!((expected - 0.995_476_4).abs() < 1e-7);
    }

    /// Values from an independent numpy implementation of the published definition (2-D
    /// Gaussian window, `scipy`-free explicit sums over every valid window position):
    /// `x[j, i] = (i * 37 + j * 91) % 256`, `y = clip(x + 20 sin(i / 3) cos(j / 5), 0, 255)` on
    /// 24 x 16 pixels gives 0.99768525; `y2 = 255 - x` gives -0.98310827.
    #[test]
    fn matches_an_independent_implementation() {
        let (w, h) = (24, 16);
        let x = plane(w, h, |i, j| ((i * 37 + j * 91) % 256) as f64);
        let y = plane(w, h, |i, j| {
            (((i * 37 + j * 91) % 256) as f64
                + 20.0 * (i as f64 / 3.0).sin() * (j as f64 / 5.0).cos())
            .clamp(0.0, 255.0)
        });
        let negative: Vec<f64> = x.iter().map(|v| 255.0 - v).collect();
        let a = ssim(&x, &y, w);
        let b = ssim(&x, &negative, w);
        assert!((a - 0.997_685_25).abs() < 1e-7, "{a}");
        assert!((b + 0.983_108_27).abs() < 1e-7, "{b}");
    }

    #[test]
    fn psnr_mse_and_pixels_off_count_what_they_say() {
        let reference = RgbaImage::from_pixel(10, 10, image::Rgba([100, 100, 100, 255]));
        let mut image = reference.clone();
        image.put_pixel(0, 0, image::Rgba([130, 100, 100, 255])); // off by 30
        image.put_pixel(1, 0, image::Rgba([105, 100, 100, 255])); // off by 5
        let e = compare(&image, &reference, 16);
        assert_eq!(e.pixels, 100);
        assert_eq!(e.pixels_off, 1);
        assert!((e.mse - (900.0 + 25.0) / 300.0).abs() < 1e-12);
        assert!((psnr(e.mse) - 10.0 * (65025.0 / e.mse).log10()).abs() < 1e-12);
        assert!(e.ssim < 1.0);
    }
}
