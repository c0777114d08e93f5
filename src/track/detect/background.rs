//! The background-motion model of a moving PINS (Note S1: a sensor on a flying MAV sees the
//! whole scene move): a robust global fit of the flow, u = a₀ + a₁x + a₂y, v = a₃ + a₄x + a₅y
//! (affine), or its translation only, by iteratively reweighted least squares with Huber
//! weights on a subsample of the pixels. Movers are outliers of the fit; the fitted field is
//! subtracted before the magnitude threshold, so only motion relative to the background counts.

use serde::{Deserialize, Serialize};

use crate::track::robust;
use crate::types::Flow;

/// Which global motion is fitted.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BackgroundModel {
    /// No model: the background is assumed still.
    None,
    /// One vector for the whole frame (a panning camera).
    Translation,
    /// Six parameters: translation, rotation, zoom and shear (a moving camera over a far or
    /// planar scene).
    Affine,
}

/// A fitted global motion field.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GlobalMotion {
    /// `[a₀, a₁, a₂, a₃, a₄, a₅]` in the frame's centred and scaled coordinates (see `at`).
    pub params: [f64; 6],
    /// Centre and scale of the coordinates: x' = (x − cx)/s, y' = (y − cy)/s.
    centre: (f64, f64),
    scale: f64,
}

impl GlobalMotion {
    /// The zero field.
    pub fn zero() -> Self {
        Self {
            params: [0.0; 6],
            centre: (0.0, 0.0),
            scale: 1.0,
        }
    }

    /// The model's flow at pixel (x, y).
    pub fn at(&self, x: f64, y: f64) -> (f64, f64) {
        let (xs, ys) = (
            (x - self.centre.0) / self.scale,
            (y - self.centre.1) / self.scale,
        );
        let a = &self.params;
        (a[0] + a[1] * xs + a[2] * ys, a[3] + a[4] * xs + a[5] * ys)
    }

    /// The largest |model flow| at the frame's four corners (px/frame).
    pub fn max_magnitude(&self, width: usize, height: usize) -> f64 {
        let (w, h) = (
            width.saturating_sub(1) as f64,
            height.saturating_sub(1) as f64,
        );
        [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h)]
            .iter()
            .map(|&(x, y)| {
                let (u, v) = self.at(x, y);
                u.hypot(v)
            })
            .fold(0.0, f64::max)
    }

    /// `flow` minus the model (unknown vectors stay unknown).
    pub fn subtract(&self, flow: &Flow) -> Flow {
        let (h, w) = (flow.height(), flow.width());
        let mut out = flow.clone();
        let (u, v) = out.planes_mut();
        for y in 0..h {
            for x in 0..w {
                let (mu, mv) = self.at(x as f64, y as f64);
                let p = y * w + x;
                u[p] -= mu as f32;
                v[p] -= mv as f32;
            }
        }
        out
    }
}

/// Fits `model` to `flow` on about `samples` pixels of a regular grid (unknown vectors are
/// skipped): IRLS with Huber weights, the Huber scale set each round to 1.345 robust standard
/// deviations (1.4826 × the median absolute residual, at least 0.01 px). Returns the zero
/// field for `BackgroundModel::None`, for a frame with too few known vectors, or when a
/// system is singular.
pub fn fit(flow: &Flow, model: BackgroundModel, samples: usize) -> GlobalMotion {
    let (h, w) = (flow.height(), flow.width());
    let mut g = GlobalMotion {
        params: [0.0; 6],
        centre: ((w as f64 - 1.0) / 2.0, (h as f64 - 1.0) / 2.0),
        scale: (w.max(h) as f64 / 2.0).max(1.0),
    };
    if model == BackgroundModel::None || h == 0 || w == 0 {
        return g;
    }
    let stride = (((h * w) as f64 / samples.max(16) as f64).sqrt().floor() as usize).max(1);
    let (u, v) = (flow.u(), flow.v());
    let mut pts: Vec<(f64, f64, f64, f64)> = Vec::new();
    for y in (stride / 2..h).step_by(stride) {
        for x in (stride / 2..w).step_by(stride) {
            let p = y * w + x;
            let (fu, fv) = (u[p] as f64, v[p] as f64);
            if fu.is_finite() && fv.is_finite() {
                pts.push((
                    (x as f64 - g.centre.0) / g.scale,
                    (y as f64 - g.centre.1) / g.scale,
                    fu,
                    fv,
                ));
            }
        }
    }
    let affine = model == BackgroundModel::Affine;
    if pts.len() < if affine { 12 } else { 4 } {
        return g;
    }
    // Start from the component-wise median: robust even when the first least squares would
    // be pulled by movers.
    // (`pts` is not empty, nor are the residuals.)
    let median = |mut v: Vec<f64>| robust::upper_median(&mut v).unwrap_or(0.0);
    g.params[0] = median(pts.iter().map(|p| p.2).collect());
    g.params[3] = median(pts.iter().map(|p| p.3).collect());
    for _ in 0..10 {
        let res: Vec<f64> = pts
            .iter()
            .map(|&(x, y, fu, fv)| {
                let a = &g.params;
                (fu - a[0] - a[1] * x - a[2] * y).hypot(fv - a[3] - a[4] * x - a[5] * y)
            })
            .collect();
        let delta = 1.345 * robust::sigma(median(res.clone())).max(0.01);
        // Weighted normal equations; u and v share the design [1, x, y] (or [1]).
        let mut ata = [[0.0f64; 3]; 3];
        let (mut atu, mut atv) = ([0.0f64; 3], [0.0f64; 3]);
        for (&(x, y, fu, fv), &r) in pts.iter().zip(&res) {
            let wgt = if r <= delta { 1.0 } else { delta / r };
            let row = [1.0, x, y];
            for i in 0..3 {
                for j in 0..3 {
                    ata[i][j] += wgt * row[i] * row[j];
                }
                atu[i] += wgt * row[i] * fu;
                atv[i] += wgt * row[i] * fv;
            }
        }
        let new = if affine {
            match (solve3(ata, atu), solve3(ata, atv)) {
                (Some(a), Some(b)) => [a[0], a[1], a[2], b[0], b[1], b[2]],
                _ => return g,
            }
        } else if ata[0][0] > 0.0 {
            [atu[0] / ata[0][0], 0.0, 0.0, atv[0] / ata[0][0], 0.0, 0.0]
        } else {
            return g;
        };
        if new.iter().any(|p| !p.is_finite()) {
            return g;
        }
        let change = new
            .iter()
            .zip(&g.params)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        g.params = new;
        if change < 1e-6 {
            break;
        }
    }
    g
}

/// Solves a 3×3 system by Gaussian elimination with partial pivoting; `None` when singular.
fn solve3(mut a: [[f64; 3]; 3], mut b: [f64; 3]) -> Option<[f64; 3]> {
    let scale = a.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    if scale <= 0.0 || !scale.is_finite() {
        return None;
    }
    for c in 0..3 {
        let p = (c..3).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))?;
        if a[p][c].abs() <= 1e-12 * scale {
            return None;
        }
        a.swap(c, p);
        b.swap(c, p);
        for r in c + 1..3 {
            let f = a[r][c] / a[c][c];
            let pivot = a[c];
            for (x, p) in a[r].iter_mut().zip(pivot).skip(c) {
                *x -= f * p;
            }
            b[r] -= f * b[c];
        }
    }
    let mut x = [0.0; 3];
    for c in (0..3).rev() {
        let s: f64 = (c + 1..3).map(|k| a[c][k] * x[k]).sum();
        x[c] = (b[c] - s) / a[c][c];
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An affine field (rotation + zoom + pan) with a mover and a few wild vectors.
    fn scene() -> (Flow, impl Fn(f64, f64) -> (f64, f64)) {
        let truth = |x: f64, y: f64| {
            (
                1.5 + 0.004 * (x - 40.0) - 0.01 * (y - 30.0),
                -0.7 + 0.01 * (x - 40.0) + 0.004 * (y - 30.0),
            )
        };
        let mut f = Flow::zeros(60, 80);
        for y in 0..60 {
            for x in 0..80 {
                let (u, v) = truth(x as f64, y as f64);
                f.set(y, x, u as f32, v as f32);
            }
        }
        for y in 10..22 {
            for x in 50..62 {
                f.set(y, x, -6.0, 3.0); // a mover: 144 px, 3 % of the frame
            }
        }
        f.set(0, 0, f32::NAN, f32::NAN);
        f.set(59, 79, 1e6, -1e6);
        (f, truth)
    }

    #[test]
    fn recovers_an_affine_field_despite_a_mover_and_removes_it() {
        let (f, truth) = scene();
        let g = fit(&f, BackgroundModel::Affine, 4000);
        for (x, y) in [(0.0, 0.0), (79.0, 0.0), (40.0, 59.0), (5.0, 50.0)] {
            let (a, b) = (g.at(x, y), truth(x, y));
            assert!(
                (a.0 - b.0).abs() < 0.01 && (a.1 - b.1).abs() < 0.01,
                "{a:?} vs {b:?} at ({x}, {y})"
            );
        }
        let rel = g.subtract(&f);
        let (u, v) = rel.get(30, 10);
        assert!(u.abs() < 0.01 && v.abs() < 0.01, "{u} {v}");
        // The mover keeps its motion relative to the background.
        let (u, v) = rel.get(15, 55);
        let (bu, bv) = truth(55.0, 15.0);
        assert!((u as f64 + bu - -6.0).abs() < 0.01 && (v as f64 + bv - 3.0).abs() < 0.01);
        assert!(rel.get(0, 0).0.is_nan());
    }

    #[test]
    fn translation_none_and_degenerate_frames() {
        let (f, truth) = scene();
        let t = fit(&f, BackgroundModel::Translation, 4000);
        let (u, v) = t.at(0.0, 0.0);
        let (cu, cv) = truth(40.0, 30.0);
        assert!((u - cu).abs() < 0.1 && (v - cv).abs() < 0.1, "{u} {v}");
        assert_eq!(t.at(0.0, 0.0), t.at(70.0, 50.0));
        assert_eq!(fit(&f, BackgroundModel::None, 4000).params, [0.0; 6]);
        // A still frame, an all-unknown frame and a 1×1 frame give the zero field.
        assert_eq!(
            fit(&Flow::zeros(30, 30), BackgroundModel::Affine, 100).params,
            [0.0; 6]
        );
        let unknown = Flow::from_vec(8, 8, vec![f32::NAN; 128]).unwrap();
        assert_eq!(fit(&unknown, BackgroundModel::Affine, 100).params, [0.0; 6]);
        assert_eq!(
            fit(&Flow::zeros(1, 1), BackgroundModel::Affine, 100).params,
            [0.0; 6]
        );
        // A single row cannot fix the y terms: singular, zero field, no panic.
        let mut row = Flow::zeros(1, 50);
        for x in 0..50 {
            row.set(0, x, 1.0 + 0.1 * x as f32, 0.0);
        }
        let g = fit(&row, BackgroundModel::Affine, 100);
        assert!(g.params.iter().all(|p| p.is_finite()));
    }
}
