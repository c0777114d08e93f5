//! Area downscaling for `--scale`: every output pixel is the mean of the input area it covers
//! (fractional pixels weighted by their coverage), separably along x then y.

use crate::error::{Error, Result};
use crate::types::Image;

/// The output size of `(h, w)` at `scale` (at least 8 pixels a side, the network's stride).
pub fn scaled_size(h: usize, w: usize, scale: f64) -> (usize, usize) {
    let s = |n: usize| ((n as f64 * scale).round() as usize).clamp(8.min(n), n);
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
    let (c, h, w) = img.shape();
    let (oh, ow) = scaled_size(h, w, scale);
    if (oh, ow) == (h, w) {
        return Ok(img.clone());
    }
    let wx = weights(w, ow);
    let wy = weights(h, oh);
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
}
