//! Image similarity (Note S7, Tables S2–S3): SSIM (Wang et al. 2004) with an 11×11 Gaussian
//! window of σ = 1.5, K1 = 0.01, K2 = 0.03, population covariances, on [0, 1] data, averaged
//! over the region where the window fits and over channels — the numbers of scikit-image's
//! `structural_similarity(gaussian_weights=True, sigma=1.5, use_sample_covariance=False,
//! data_range=1)` — and MAE and MSE.

use serde::Serialize;

use crate::error::{Error, Result};
use crate::types::Image;

/// The three numbers of Tables S2–S3.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Similarity {
    pub ssim: f64,
    pub mae: f64,
    pub mse: f64,
}

const SIGMA: f64 = 1.5;
/// scikit-image truncates its Gaussian at 3.5 σ: radius int(3.5·1.5 + 0.5) = 5, an 11×11 window.
const RADIUS: usize = 5;

fn gaussian_window() -> Vec<f64> {
    let w: Vec<f64> = (0..=2 * RADIUS)
        .map(|i| (-((i as f64 - RADIUS as f64).powi(2)) / (2.0 * SIGMA * SIGMA)).exp())
        .collect();
    let s: f64 = w.iter().sum();
    w.into_iter().map(|v| v / s).collect()
}

/// Separable Gaussian filter over the valid region: `[H, W]` → `[H − 10, W − 10]`.
fn filter_valid(p: &[f64], h: usize, w: usize, g: &[f64]) -> Vec<f64> {
    let k = g.len();
    let (oh, ow) = (h + 1 - k, w + 1 - k);
    let mut rows = vec![0.0; h * ow];
    for y in 0..h {
        for x in 0..ow {
            rows[y * ow + x] = (0..k).map(|j| g[j] * p[y * w + x + j]).sum();
        }
    }
    let mut out = vec![0.0; oh * ow];
    for y in 0..oh {
        for x in 0..ow {
            out[y * ow + x] = (0..k).map(|i| g[i] * rows[(y + i) * ow + x]).sum();
        }
    }
    out
}

/// Mean SSIM of one channel pair.
fn ssim_plane(a: &[f32], b: &[f32], h: usize, w: usize) -> f64 {
    let g = gaussian_window();
    let (c1, c2) = ((0.01f64).powi(2), (0.03f64).powi(2));
    let x: Vec<f64> = a.iter().map(|&v| v as f64).collect();
    let y: Vec<f64> = b.iter().map(|&v| v as f64).collect();
    let prod = |p: &[f64], q: &[f64]| p.iter().zip(q).map(|(u, v)| u * v).collect::<Vec<f64>>();
    let (ux, uy) = (filter_valid(&x, h, w, &g), filter_valid(&y, h, w, &g));
    let (uxx, uyy, uxy) = (
        filter_valid(&prod(&x, &x), h, w, &g),
        filter_valid(&prod(&y, &y), h, w, &g),
        filter_valid(&prod(&x, &y), h, w, &g),
    );
    let n = ux.len();
    let mut sum = 0.0;
    for i in 0..n {
        let (vx, vy, vxy) = (
            uxx[i] - ux[i] * ux[i],
            uyy[i] - uy[i] * uy[i],
            uxy[i] - ux[i] * uy[i],
        );
        let num = (2.0 * ux[i] * uy[i] + c1) * (2.0 * vxy + c2);
        let den = (ux[i] * ux[i] + uy[i] * uy[i] + c1) * (vx + vy + c2);
        sum += num / den;
    }
    sum / n as f64
}

/// SSIM, MAE and MSE of two images of the same shape, at least 11×11.
pub fn compare(a: &Image, b: &Image) -> Result<Similarity> {
    if a.shape() != b.shape() {
        let (c1, h1, w1) = a.shape();
        let (c2, h2, w2) = b.shape();
        return Err(Error::shape(
            "second image",
            format!("{c1}x{h1}x{w1} (the first)"),
            format!("{c2}x{h2}x{w2}"),
        ));
    }
    let (c, h, w) = a.shape();
    if h < 2 * RADIUS + 1 || w < 2 * RADIUS + 1 {
        return Err(Error::invalid(
            "image size",
            format!("{w}x{h}: SSIM needs at least 11x11 pixels"),
        ));
    }
    a.check_finite("first image")?;
    b.check_finite("second image")?;
    let ssim = (0..c)
        .map(|ch| ssim_plane(a.plane(ch), b.plane(ch), h, w))
        .sum::<f64>()
        / c as f64;
    let n = a.data().len() as f64;
    let (mut mae, mut mse) = (0.0, 0.0);
    for (&p, &q) in a.data().iter().zip(b.data()) {
        let d = p as f64 - q as f64;
        mae += d.abs();
        mse += d * d;
    }
    Ok(Similarity {
        ssim,
        mae: mae / n,
        mse: mse / n,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic test images, also built by the reference script in the test below.
    pub fn pattern(c: usize, h: usize, w: usize, phase: f64) -> Image {
        let mut img = Image::zeros(c, h, w);
        for ch in 0..c {
            for y in 0..h {
                for x in 0..w {
                    let v = 0.5
                        + 0.3
                            * ((x as f64 * 0.3 + phase + ch as f64).sin()
                                * (y as f64 * 0.17 - phase).cos())
                        + 0.1 * (((x * 7 + y * 13 + ch * 5) % 11) as f64 / 11.0 - 0.5);
                    img.set(ch, y, x, v as f32);
                }
            }
        }
        img
    }

    #[test]
    fn identical_images_and_bad_sizes() {
        let a = pattern(3, 20, 30, 0.0);
        let s = compare(&a, &a).unwrap();
        assert!((s.ssim - 1.0).abs() < 1e-12 && s.mae == 0.0 && s.mse == 0.0);
        assert!(compare(&a, &pattern(3, 20, 31, 0.0)).is_err());
        assert!(compare(&pattern(1, 10, 30, 0.0), &pattern(1, 10, 30, 0.0)).is_err());
    }

    #[test]
    fn matches_scikit_image() {
        // Reference from scikit-image 0.26 (structural_similarity(a, b, channel_axis=0,
        // gaussian_weights=True, sigma=1.5, use_sample_covariance=False, data_range=1)) on
        // the same float32 images, built by this pattern() in numpy.
        let (a, b) = (pattern(3, 40, 48, 0.0), pattern(3, 40, 48, 0.4));
        let s = compare(&a, &b).unwrap();
        assert!(
            (s.ssim - SKIMAGE_SSIM).abs() < 1e-4,
            "ssim {} vs {}",
            s.ssim,
            SKIMAGE_SSIM
        );
        assert!(
            (s.mae - NUMPY_MAE).abs() < 1e-6 && (s.mse - NUMPY_MSE).abs() < 1e-7,
            "{s:?}"
        );
    }

    const SKIMAGE_SSIM: f64 = 0.833_764_6;
    const NUMPY_MAE: f64 = 0.074_361_06;
    const NUMPY_MSE: f64 = 0.006_822_84;
}
