//! A flow field at another size: the frames' planes resampled (area-averaged where they shrink,
//! bilinear where they grow) and each vector scaled by its axis' size ratio. Used wherever flow
//! moves between resolutions: the coarse start (`flow::infer`), the refinement's pyramid
//! (`flow::refine`) and MMS at another scale (`flow::scale`).

use crate::error::{Error, Result};
use crate::imaging::resize::resize_to;
use crate::types::{Flow, Image};

/// `flow` `[2, h', w']` resampled to `[2, h, w]` (per axis area-averaged where it shrinks,
/// bilinear between pixel centres where it grows, `align_corners = false`, borders clamped),
/// u multiplied by w / w' and v by h / h'. A NaN (unknown) vector spreads to every output
/// vector that reads it.
pub fn resize_flow(flow: &Flow, h: usize, w: usize) -> Result<Flow> {
    let (fh, fw) = (flow.height(), flow.width());
    if fh == 0 || fw == 0 || h == 0 || w == 0 {
        return Err(Error::invalid(
            "flow size",
            format!("cannot resample a {fw}x{fh} flow to {w}x{h}"),
        ));
    }
    if (fh, fw) == (h, w) {
        return Ok(flow.clone());
    }
    let planes = Image::from_vec(2, fh, fw, flow.data().to_vec())?;
    let mut data = resize_to(&planes, h, w)?.into_vec();
    let (su, sv) = (w as f32 / fw as f32, h as f32 / fh as f32);
    let n = h * w;
    data[..n].iter_mut().for_each(|u| *u *= su);
    data[n..].iter_mut().for_each(|v| *v *= sv);
    Flow::from_vec(h, w, data)
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
        let full = resize_flow(&half, h, w).expect("resample");
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
        assert_eq!(resize_flow(&f, 5, 7).expect("same size"), f);
        assert!(resize_flow(&f, 0, 7).is_err());
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
        let g = resize_flow(&f, 12, 8).expect("resample");
        assert!(g.u().iter().all(|&u| (u - 2.0).abs() < 1e-6));
        assert!(g.v().iter().all(|&v| (v - 3.0).abs() < 1e-6));
    }

    /// Down again: a uniform flow keeps its vectors scaled by the size ratio, and a flow
    /// brought up and back down by an integer factor returns to itself.
    #[test]
    fn downsampling_averages_and_scales_the_vectors() {
        let mut f = Flow::zeros(6, 8);
        for y in 0..6 {
            for x in 0..8 {
                f.set(y, x, 0.3 * x as f32, -0.2 * y as f32);
            }
        }
        let up = resize_flow(&f, 12, 16).expect("up");
        let back = resize_flow(&up, 6, 8).expect("down");
        for y in 1..5 {
            for x in 1..7 {
                let (a, b) = (f.get(y, x), back.get(y, x));
                assert!(
                    (a.0 - b.0).abs() < 1e-5 && (a.1 - b.1).abs() < 1e-5,
                    "{a:?} {b:?}"
                );
            }
        }
    }
}
