//! Resampling for `--scale`: downscaling takes every output pixel as the mean of the input area
//! it covers (fractional pixels weighted by their coverage); upscaling interpolates bilinearly
//! between pixel centres (`align_corners = false`, borders clamped); both separably along x
//! then y.

use crate::error::{Error, Result};
use crate::types::Image;

/// The output size of `(h, w)` at `scale` (at least 8 pixels a side, the network's stride,
/// or the input's own size when it is smaller).
pub fn scaled_size(h: usize, w: usize, scale: f64) -> (usize, usize) {
    let s = |n: usize| ((n as f64 * scale).round() as usize).max(8.min(n));
    (s(h), s(w))
}

/// `img` scaled by `scale` in (0, 1]; 1 returns a copy.
pub fn downscale(img: &Image, scale: f64) -> Result<Image> {
    if !(scale.is_finite() && scale > 0.0 && scale <= 1.0) {
        return Err(Error::invalid(
            "--scale",
            format!("must be in (0, 1], got {scale}"),
        ));
    }
    let (_, h, w) = img.shape();
    let (oh, ow) = scaled_size(h, w, scale);
    resize_to(img, oh, ow)
}

/// `img` resampled to `oh × ow`: each axis area-averaged where it shrinks, interpolated
/// bilinearly where it grows; its own size returns a copy.
pub fn resize_to(img: &Image, oh: usize, ow: usize) -> Result<Image> {
    let (c, h, w) = img.shape();
    if oh == 0 || ow == 0 || h == 0 || w == 0 {
        return Err(Error::invalid(
            "resize",
            format!("cannot resample a {w}x{h} image to {ow}x{oh}"),
        ));
    }
    if (oh, ow) == (h, w) {
        return Ok(img.clone());
    }
    let taps = |n: usize, m: usize| {
        if m <= n {
            weights(n, m)
        } else {
            bilinear(n, m)
        }
    };
    let wx = taps(w, ow);
    let wy = taps(h, oh);
    let mut out = vec![0.0f32; c * oh * ow];
    let mut row = vec![0.0f32; h * ow];
    for ch in 0..c {
        let p = img.plane(ch);
        for y in 0..h {
            for (ox, taps) in wx.iter().enumerate() {
                row[y * ow + ox] = taps.iter().map(|&(i, k)| p[y * w + i] * k).sum();
            }
        }
        let o = &mut out[ch * oh * ow..(ch + 1) * oh * ow];
        for (oy, taps) in wy.iter().enumerate() {
            for ox in 0..ow {
                o[oy * ow + ox] = taps.iter().map(|&(i, k)| row[i * ow + ox] * k).sum();
            }
        }
    }
    Image::from_vec(c, oh, ow, out)
}

/// Bilinear taps from `n` inputs to `m` outputs, pixel centres aligned (`align_corners =
/// false`): output `o` reads input position (o + ½)·n/m − ½, clamped to the border.
fn bilinear(n: usize, m: usize) -> Vec<Vec<(usize, f32)>> {
    let r = n as f64 / m as f64;
    (0..m)
        .map(|o| {
            let s = ((o as f64 + 0.5) * r - 0.5).clamp(0.0, (n - 1) as f64);
            let i0 = s.floor() as usize;
            let i1 = (i0 + 1).min(n - 1);
            let f = (s - i0 as f64) as f32;
            vec![(i0, 1.0 - f), (i1, f)]
        })
        .collect()
}

/// For each output index, the input indices it covers and their weights (summing to 1).
fn weights(n: usize, m: usize) -> Vec<Vec<(usize, f32)>> {
    let r = n as f64 / m as f64;
    (0..m)
        .map(|o| {
            let (a, b) = (o as f64 * r, (o + 1) as f64 * r);
            let mut taps = Vec::new();
            let mut i = a.floor() as usize;
            while (i as f64) < b && i < n {
                let cover = (b.min(i as f64 + 1.0) - a.max(i as f64)).max(0.0);
                if cover > 0.0 {
                    taps.push((i, (cover / r) as f32));
                }
                i += 1;
            }
            taps
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn area_means_keep_the_mean_and_halve_exactly() {
        let (h, w) = (16, 24);
        let data: Vec<f32> = (0..h * w).map(|v| v as f32).collect();
        let img = Image::from_vec(1, h, w, data.clone()).unwrap();
        let half = downscale(&img, 0.5).unwrap();
        assert_eq!(half.shape(), (1, 8, 12));
        let want = (0.0 + 1.0 + w as f32 + (w + 1) as f32) / 4.0;
        assert_eq!(half.get(0, 0, 0), want);
        let mean = |d: &[f32]| d.iter().map(|&v| v as f64).sum::<f64>() / d.len() as f64;
        let odd = downscale(&img, 0.7).unwrap();
        assert_eq!(odd.shape(), (1, 11, 17));
        assert!((mean(odd.data()) - mean(img.data())).abs() < 1.0);
        assert!(downscale(&img, 0.0).is_err() && downscale(&img, 1.5).is_err());
        assert_eq!(downscale(&img, 1.0).unwrap(), img);
        // Never below the network's stride of 8 pixels.
        assert_eq!(downscale(&img, 0.1).unwrap().shape(), (1, 8, 8));
    }

    /// Upscaling interpolates between pixel centres: a linear ramp stays a linear ramp (with
    /// the new spacing) inside the frame, and is clamped at the borders.
    #[test]
    fn bilinear_upscaling_keeps_a_ramp() {
        let (h, w) = (6, 10);
        let data: Vec<f32> = (0..h * w).map(|i| (i % w) as f32 * 2.0).collect();
        let img = Image::from_vec(1, h, w, data).unwrap();
        let big = resize_to(&img, 9, 15).unwrap();
        assert_eq!(big.shape(), (1, 9, 15));
        for x in 1..14 {
            // Output x reads input position (x + ½)·10/15 − ½.
            let want = 2.0 * ((x as f32 + 0.5) * 10.0 / 15.0 - 0.5).clamp(0.0, 9.0);
            assert!(
                (big.get(0, 4, x) - want).abs() < 1e-4,
                "x {x}: {}",
                big.get(0, 4, x)
            );
        }
        assert_eq!(big.get(0, 0, 0), 0.0);
        assert!(resize_to(&img, 0, 4).is_err());
        assert_eq!(resize_to(&img, 6, 10).unwrap(), img);
    }
}
