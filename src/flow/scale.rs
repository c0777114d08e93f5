//! Flow at a reduced resolution (the whole system's speed knob, Notes S13–S15): both frames
//! area-downscaled by `scale`, MMS run on them, and the flow brought back to the frames' size by
//! bilinear interpolation with its vectors multiplied by the size ratio, so a tracker and its
//! truth keep working in the full frame's pixels.

use super::infer::Predictor;
use crate::error::{Error, Result};
use crate::imaging::resize::downscale;
use crate::types::{Flow, Image};

/// The flow from `img1` to `img2` estimated at `scale` ∈ (0, 1] of their size, returned at
/// their size. `scale = 1` is `Predictor::predict` itself.
pub fn predict_scaled(
    predictor: &Predictor,
    img1: &Image,
    img2: &Image,
    iters: usize,
    scale: f64,
) -> Result<Flow> {
    let (_, h, w) = img1.shape();
    if scale == 1.0 {
        return predictor.predict(img1, img2, iters);
    }
    let (a, b) = (downscale(img1, scale)?, downscale(img2, scale)?);
    if a.shape() == img1.shape() {
        return predictor.predict(img1, img2, iters);
    }
    upsample_flow(&predictor.predict(&a, &b, iters)?, h, w)
}

/// `flow` `[2, h', w']` resampled to `[2, h, w]` (pixel centres aligned, `align_corners =
/// false`, borders clamped), u multiplied by w / w' and v by h / h'. A NaN (unknown) vector
/// spreads to every output vector that reads it.
pub fn upsample_flow(flow: &Flow, h: usize, w: usize) -> Result<Flow> {
    let (fh, fw) = (flow.height(), flow.width());
    if fh == 0 || fw == 0 || h == 0 || w == 0 {
        return Err(Error::invalid(
            "flow size",
            format!("cannot resample a {fw}x{fh} flow to {w}x{h}"),
        ));
    }
    let (ry, rx) = (fh as f64 / h as f64, fw as f64 / w as f64);
    // For each output coordinate: the two source indices and the weight of the second.
    let taps = |n: usize, r: f64, m: usize| -> Vec<(usize, usize, f32)> {
        (0..n)
            .map(|o| {
                let s = ((o as f64 + 0.5) * r - 0.5).clamp(0.0, (m - 1) as f64);
                let i0 = s.floor() as usize;
                let i1 = (i0 + 1).min(m - 1);
                (i0, i1, (s - i0 as f64) as f32)
            })
            .collect()
    };
    let (ty, tx) = (taps(h, ry, fh), taps(w, rx, fw));
    let (su, sv) = ((1.0 / rx) as f32, (1.0 / ry) as f32);
    let mut out = vec![0.0f32; 2 * h * w];
    for (plane, (src, k)) in [(flow.u(), su), (flow.v(), sv)].into_iter().enumerate() {
        let dst = &mut out[plane * h * w..(plane + 1) * h * w];
        for (y, &(y0, y1, fy)) in ty.iter().enumerate() {
            for (x, &(x0, x1, fx)) in tx.iter().enumerate() {
                let top = src[y0 * fw + x0] * (1.0 - fx) + src[y0 * fw + x1] * fx;
                let bottom = src[y1 * fw + x0] * (1.0 - fx) + src[y1 * fw + x1] * fx;
                dst[y * w + x] = (top * (1.0 - fy) + bottom * fy) * k;
            }
        }
    }
    Flow::from_vec(h, w, out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An affine flow u = a + b·x, v = c + d·y sampled at half resolution comes back exact
    /// inside the frame: bilinear interpolation reproduces affine fields, and the vectors are
    /// doubled with the size.
    #[test]
    fn affine_flow_survives_a_round_trip() {
        let (h, w) = (24, 40);
        let (fh, fw) = (12, 20);
        let mut half = Flow::zeros(fh, fw);
        for y in 0..fh {
            for x in 0..fw {
                half.set(y, x, 0.5 + 0.1 * x as f32, -1.0 + 0.05 * y as f32);
            }
        }
        let full = upsample_flow(&half, h, w).expect("resample");
        // Away from the clamped border, full-res pixel x sits at half-res (x + 0.5) / 2 - 0.5.
        for y in 1..h - 1 {
            for x in 1..w - 1 {
                let sx = (x as f32 + 0.5) / 2.0 - 0.5;
                let sy = (y as f32 + 0.5) / 2.0 - 0.5;
                let (u, v) = full.get(y, x);
                assert!(
                    (u - 2.0 * (0.5 + 0.1 * sx)).abs() < 1e-5,
                    "u at ({y},{x}): {u}"
                );
                assert!(
                    (v - 2.0 * (-1.0 + 0.05 * sy)).abs() < 1e-5,
                    "v at ({y},{x}): {v}"
                );
            }
        }
    }

    #[test]
    fn same_size_is_identity_and_empty_is_an_error() {
        let mut f = Flow::zeros(5, 7);
        f.set(2, 3, 1.5, -2.0);
        assert_eq!(upsample_flow(&f, 5, 7).expect("same size"), f);
        assert!(upsample_flow(&f, 0, 7).is_err());
    }

    /// Non-square ratios scale u and v each by their own axis.
    #[test]
    fn vectors_scale_per_axis() {
        let mut f = Flow::zeros(4, 4);
        for y in 0..4 {
            for x in 0..4 {
                f.set(y, x, 1.0, 1.0);
            }
        }
        let g = upsample_flow(&f, 12, 8).expect("resample");
        assert!(g.u().iter().all(|&u| (u - 2.0).abs() < 1e-6));
        assert!(g.v().iter().all(|&v| (v - 3.0).abs() < 1e-6));
    }
}
