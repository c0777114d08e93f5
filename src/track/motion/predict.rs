//! Trajectory extrapolation of Note S13 (Eqs. S20–S23): weighted polynomial regression of the
//! recent speeds and of the sine and cosine of the directions (linearly increasing weights, on
//! a centred and scaled time axis), then the velocity integrated over sub-steps Δt = T/5.

use crate::error::{Error, Result};

/// A 1-D polynomial fitted by weighted least squares on t' = (t − centre) / scale.
#[derive(Clone, Debug, PartialEq)]
pub struct Poly1 {
    pub coefficients: Vec<f64>,
    pub centre: f64,
    pub scale: f64,
}

impl Poly1 {
    /// Fits `values` at times `t` with `weights`, at the highest order ≤ `order` that the data
    /// determine: a window of equal samples or of fewer points falls back to a lower order
    /// (down to a constant) instead of producing a singular system.
    pub fn fit(t: &[f64], values: &[f64], weights: &[f64], order: usize) -> Result<Self> {
        if t.is_empty() || t.len() != values.len() || t.len() != weights.len() {
            return Err(Error::invalid(
                "polynomial fit",
                "times, values and weights must be non-empty and of one length",
            ));
        }
        if values
            .iter()
            .chain(t)
            .chain(weights)
            .any(|v| !v.is_finite())
            || weights.iter().any(|&w| w < 0.0)
        {
            return Err(Error::invalid(
                "polynomial fit",
                "non-finite sample or negative weight",
            ));
        }
        let n = t.len();
        let centre = t.iter().sum::<f64>() / n as f64;
        let scale = t
            .iter()
            .map(|x| (x - centre).abs())
            .fold(0.0, f64::max)
            .max(1e-9);
        let mut order = order.min(n - 1);
        loop {
            if let Some(c) = solve(t, values, weights, order, centre, scale) {
                return Ok(Self {
                    coefficients: c,
                    centre,
                    scale,
                });
            }
            if order == 0 {
                // All weights zero: fall back to the plain mean.
                return Ok(Self {
                    coefficients: vec![values.iter().sum::<f64>() / n as f64],
                    centre,
                    scale,
                });
            }
            order -= 1;
        }
    }

    pub fn eval(&self, t: f64) -> f64 {
        let u = (t - self.centre) / self.scale;
        self.coefficients
            .iter()
            .rev()
            .fold(0.0, |acc, c| acc * u + c)
    }
}

/// Weighted normal equations on the scaled axis, solved by Gaussian elimination with partial
/// pivoting; `None` when (near-)singular. The system is at most 7×7 and well scaled.
fn solve(
    t: &[f64],
    y: &[f64],
    w: &[f64],
    order: usize,
    centre: f64,
    scale: f64,
) -> Option<Vec<f64>> {
    let m = order + 1;
    let mut a = vec![vec![0.0; m + 1]; m];
    for ((&ti, &yi), &wi) in t.iter().zip(y).zip(w) {
        let u = (ti - centre) / scale;
        let pows: Vec<f64> = (0..m).map(|k| u.powi(k as i32)).collect();
        for r in 0..m {
            for c in 0..m {
                a[r][c] += wi * pows[r] * pows[c];
            }
            a[r][m] += wi * pows[r] * yi;
        }
    }
    let norm = a
        .iter()
        .map(|r| r[..m].iter().map(|v| v.abs()).fold(0.0, f64::max))
        .fold(0.0, f64::max);
    for col in 0..m {
        let piv = (col..m).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[piv][col].abs() <= 1e-10 * norm.max(1e-300) {
            return None;
        }
        a.swap(col, piv);
        let pivot_row = a[col].clone();
        for (r, row) in a.iter_mut().enumerate() {
            if r != col {
                let f = row[col] / pivot_row[col];
                for (x, p) in row[col..=m].iter_mut().zip(&pivot_row[col..=m]) {
                    *x -= f * p;
                }
            }
        }
    }
    Some((0..m).map(|i| a[i][m] / a[i][i]).collect())
}

/// The motion model fitted on a window: speed(t) and direction(t) = atan2(sin(t), cos(t)).
#[derive(Clone, Debug)]
pub struct MotionFit {
    pub speed: Poly1,
    pub sin: Poly1,
    pub cos: Poly1,
    /// Time (frame index) of the last sample.
    pub now: f64,
    /// The window's time span (last sample's time − first's, frames).
    pub span: f64,
    /// Beyond this many frames after `now` the velocity is held at its value there, the
    /// fitted trend no longer followed; `None`: followed all the way (Eq. S22's).
    pub hold_after: Option<f64>,
}

/// Fits Eqs. S20–S21 on the window `(t, speed, direction)` with linearly increasing weights.
/// Samples whose direction is undefined (a still object) count in the speed fit only.
/// The order a window of `samples` supports: `order`, lowered until the window holds
/// min(`window`, `per_order` × k + 1) samples for order k. A track's first fits would
/// otherwise pass a polynomial through its few noisy samples, and its extrapolation 30 frames
/// ahead runs hundreds of pixels off. The full window always supports the full order (Note
/// S14's fits of L = 10 are the paper's); `per_order` 1 lowers it only where the fit would be
/// underdetermined (order ≤ samples − 1).
pub fn supported_order(order: usize, samples: usize, window: usize, per_order: usize) -> usize {
    (0..=order)
        .rev()
        .find(|&k| samples >= (per_order.saturating_mul(k).saturating_add(1)).min(window))
        .unwrap_or(0)
}

pub fn fit_motion(samples: &[(f64, f64, Option<f64>)], order: usize) -> Result<MotionFit> {
    if samples.is_empty() {
        return Err(Error::invalid("trajectory window", "no samples"));
    }
    let n = samples.len();
    let weights: Vec<f64> = (1..=n).map(|k| k as f64).collect();
    let t: Vec<f64> = samples.iter().map(|s| s.0).collect();
    let speed = Poly1::fit(
        &t,
        &samples.iter().map(|s| s.1).collect::<Vec<_>>(),
        &weights,
        order,
    )?;
    let dirs: Vec<(f64, f64, f64)> = samples
        .iter()
        .zip(&weights)
        .filter_map(|(s, &w)| s.2.map(|d| (s.0, d, w)))
        .collect();
    let (sin, cos) = if dirs.is_empty() {
        let zero = Poly1 {
            coefficients: vec![0.0],
            centre: 0.0,
            scale: 1.0,
        };
        (
            zero.clone(),
            Poly1 {
                coefficients: vec![1.0],
                ..zero
            },
        )
    } else {
        let td: Vec<f64> = dirs.iter().map(|d| d.0).collect();
        let wd: Vec<f64> = dirs.iter().map(|d| d.2).collect();
        (
            Poly1::fit(
                &td,
                &dirs.iter().map(|d| d.1.sin()).collect::<Vec<_>>(),
                &wd,
                order,
            )?,
            Poly1::fit(
                &td,
                &dirs.iter().map(|d| d.1.cos()).collect::<Vec<_>>(),
                &wd,
                order,
            )?,
        )
    };
    Ok(MotionFit {
        speed,
        sin,
        cos,
        now: t[n - 1],
        span: t[n - 1] - t[0],
        hold_after: None,
    })
}

impl MotionFit {
    /// Velocity (pixels per frame) at time `t`; the speed is kept non-negative.
    pub fn velocity(&self, t: f64) -> (f64, f64) {
        let s = self.speed.eval(t).max(0.0);
        let d = self.sin.eval(t).atan2(self.cos.eval(t));
        (s * d.cos(), s * d.sin())
    }

    /// Eq. S23: positions at 1…`k` frames ahead of `start`, integrating the velocity over five
    /// sub-steps per frame (midpoint rule); past `hold_after` the velocity stays as it is there.
    pub fn extrapolate(&self, start: (f64, f64), k: usize) -> Vec<(f64, f64)> {
        let dt = 0.2;
        let (mut x, mut y) = start;
        let mut out = Vec::with_capacity(k);
        let last = self.now + self.hold_after.map_or(f64::INFINITY, |h| h.max(0.0));
        for frame in 0..k {
            for m in 0..5 {
                let t = (self.now + frame as f64 + (m as f64 + 0.5) * dt).min(last);
                let (vx, vy) = self.velocity(t);
                x += vx * dt;
                y += vy * dt;
            }
            out.push((x, y));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_order_waits_for_its_samples_and_the_full_window_has_it() {
        // L = 30, n = 2, five samples per order: constant up to 5 samples, linear from 6,
        // quadratic from 11.
        let got: Vec<usize> = (1..=12).map(|s| supported_order(2, s, 30, 5)).collect();
        assert_eq!(got, vec![0, 0, 0, 0, 0, 1, 1, 1, 1, 1, 2, 2]);
        // A full window of 8 has the full order, however few samples that is per order.
        assert_eq!(supported_order(2, 8, 8, 5), 2);
        assert_eq!(supported_order(2, 7, 8, 5), 1);
        // One sample per order: the highest order the samples determine.
        assert_eq!(supported_order(2, 2, 30, 1), 1);
        assert_eq!(supported_order(2, 3, 30, 1), 2);
        assert_eq!(supported_order(3, 0, 30, 5), 0);
        assert_eq!(supported_order(2, 40, 30, usize::MAX), 2);
    }
    use std::f64::consts::PI;

    #[test]
    fn constant_motion_extrapolates_exactly() {
        let samples: Vec<(f64, f64, Option<f64>)> =
            (0..30).map(|n| (n as f64, 3.0, Some(PI / 6.0))).collect();
        let fit = fit_motion(&samples, 2).unwrap();
        let p = fit.extrapolate((10.0, 20.0), 15);
        let expect = (
            10.0 + 45.0 * (PI / 6.0).cos(),
            20.0 + 45.0 * (PI / 6.0).sin(),
        );
        assert!((p[14].0 - expect.0).abs() < 1e-9 && (p[14].1 - expect.1).abs() < 1e-9);
    }

    #[test]
    fn past_hold_after_the_velocity_is_held() {
        // Speed 1 + 0.1 t along +x over t = 0…9: the fit is the ramp itself.
        let samples: Vec<(f64, f64, Option<f64>)> = (0..10)
            .map(|n| (n as f64, 1.0 + 0.1 * n as f64, Some(0.0)))
            .collect();
        let mut fit = fit_motion(&samples, 1).unwrap();
        assert!((fit.span - 9.0).abs() < 1e-12);
        let speed = |t: f64| 1.0 + 0.1 * t;
        // Followed all the way: ∫ from 9 to 39 of the ramp.
        let all = fit.extrapolate((0.0, 0.0), 30)[29].0;
        let integral = |a: f64, b: f64| (b - a) + 0.05 * (b * b - a * a);
        assert!((all - integral(9.0, 39.0)).abs() < 1e-6, "{all}");
        // Held after 9 frames: the ramp to t = 18, then its speed there for 21 frames.
        fit.hold_after = Some(fit.span);
        let held = fit.extrapolate((0.0, 0.0), 30);
        assert!((held[29].0 - (integral(9.0, 18.0) + 21.0 * speed(18.0))).abs() < 1e-6);
        // Up to the hold the two agree.
        assert!((held[8].0 - fit.extrapolate((0.0, 0.0), 9)[8].0).abs() < 1e-12);
        assert!(held.iter().all(|p| p.1.abs() < 1e-9));
    }

    #[test]
    fn wraps_around_pi_and_survives_degenerate_windows() {
        // Directions alternating across ±π: the sine/cosine fit points left, not right.
        let samples: Vec<(f64, f64, Option<f64>)> = (0..10)
            .map(|n| {
                (
                    n as f64,
                    2.0,
                    Some(if n % 2 == 0 { PI - 0.01 } else { -PI + 0.01 }),
                )
            })
            .collect();
        let fit = fit_motion(&samples, 2).unwrap();
        assert!(fit.velocity(10.0).0 < -1.9);
        // One sample, a still object, huge speeds: finite predictions.
        for samples in [
            vec![(0.0, 1.0, Some(0.3))],
            vec![(0.0, 0.0, None), (1.0, 0.0, None)],
            (0..5).map(|n| (n as f64, 1e12, Some(1.0))).collect(),
        ] {
            let fit = fit_motion(&samples, 3).unwrap();
            assert!(
                fit.extrapolate((0.0, 0.0), 30)
                    .iter()
                    .all(|p| p.0.is_finite() && p.1.is_finite())
            );
        }
        assert!(fit_motion(&[], 2).is_err());
        assert!(Poly1::fit(&[0.0, 1.0], &[f64::NAN, 1.0], &[1.0, 1.0], 1).is_err());
    }
}
