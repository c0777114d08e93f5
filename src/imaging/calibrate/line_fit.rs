//! The photon-transfer line σ² = a·μ + b (Note S4, Eq. S3) through measured (mean, variance)
//! points: weighted least squares with each point's weight the inverse variance of a sample
//! variance (2σ⁴ over its degrees of freedom, σ² the fitted line's), made robust by Huber's
//! weights on the residuals over their own spread (1.4826·MAD), and 95 % confidence intervals
//! from the covariance scaled by the residuals' reduced χ² and Student's t.

use crate::error::{Error, Result};

/// A fitted line and what it is worth.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct LineFit {
    /// Slope: DN of variance per DN of signal (Eq. S3's a).
    pub a: f64,
    /// Intercept: the variance at zero signal (Eq. S3's b, DN²).
    pub b: f64,
    /// 95 % confidence intervals.
    pub a_ci: [f64; 2],
    pub b_ci: [f64; 2],
    /// Root mean square of the residuals relative to the fitted variance.
    pub relative_rms: f64,
    /// Points fitted.
    pub points: usize,
    /// Their final robust weights' sum over their count (1: none down-weighted).
    pub inlier_share: f64,
}

/// Huber's tuning constant (95 % efficiency under Gaussian residuals).
const HUBER: f64 = 1.345;

/// Fits through `points` = (mean, variance, degrees of freedom of the variance), at least 3.
pub fn fit_line(points: &[(f64, f64, usize)]) -> Result<LineFit> {
    let n = points.len();
    if n < 3 {
        return Err(Error::invalid(
            "photon transfer",
            format!("{n} points; a line with intervals needs at least 3"),
        ));
    }
    if points
        .iter()
        .any(|p| !(p.0.is_finite() && p.1.is_finite()) || p.2 == 0)
    {
        return Err(Error::invalid("photon transfer", "a point is not finite"));
    }
    let mut robust = vec![1.0; n];
    let (mut a, mut b) = solve(points, &vec![1.0; n])?;
    for _ in 0..20 {
        // Inverse-variance weights at the current line (floored: a line through zero).
        let base: Vec<f64> = points
            .iter()
            .map(|&(x, y, dof)| {
                let s2 = (a * x + b).max(1e-3 * y.abs()).max(1e-9);
                dof as f64 / (2.0 * s2 * s2)
            })
            .collect();
        let w: Vec<f64> = base.iter().zip(&robust).map(|(b, r)| b * r).collect();
        let (na, nb) = solve(points, &w)?;
        let r: Vec<f64> = points
            .iter()
            .zip(&base)
            .map(|(&(x, y, _), wb)| (y - (na * x + nb)) * wb.sqrt())
            .collect();
        let scale = 1.4826 * median(&r.iter().map(|v| v.abs()).collect::<Vec<_>>());
        robust = r
            .iter()
            .map(|v| {
                let u = v.abs() / scale.max(1e-12);
                if u <= HUBER { 1.0 } else { HUBER / u }
            })
            .collect();
        let done = (na - a).abs() <= 1e-12 * na.abs().max(1e-12)
            && (nb - b).abs() <= 1e-12 * nb.abs().max(1e-12);
        (a, b) = (na, nb);
        if done {
            break;
        }
    }
    // Covariance of (a, b), scaled by the reduced χ² of the weighted residuals.
    let w: Vec<f64> = points
        .iter()
        .zip(&robust)
        .map(|(&(x, y, dof), r)| {
            let s2 = (a * x + b).max(1e-3 * y.abs()).max(1e-9);
            r * dof as f64 / (2.0 * s2 * s2)
        })
        .collect();
    let (sw, sx, sxx) = points.iter().zip(&w).fold((0.0, 0.0, 0.0), |acc, (p, wi)| {
        (acc.0 + wi, acc.1 + wi * p.0, acc.2 + wi * p.0 * p.0)
    });
    let det = sw * sxx - sx * sx;
    let chi2: f64 = points
        .iter()
        .zip(&w)
        .map(|(&(x, y, _), wi)| wi * (y - a * x - b).powi(2))
        .sum::<f64>()
        / (n - 2) as f64;
    let t = student_t_975(n - 2);
    let sa = (sw / det * chi2).sqrt();
    let sb = (sxx / det * chi2).sqrt();
    let relative_rms = (points
        .iter()
        .map(|&(x, y, _)| ((y - a * x - b) / (a * x + b).abs().max(1e-9)).powi(2))
        .sum::<f64>()
        / n as f64)
        .sqrt();
    Ok(LineFit {
        a,
        b,
        a_ci: [a - t * sa, a + t * sa],
        b_ci: [b - t * sb, b + t * sb],
        relative_rms,
        points: n,
        inlier_share: robust.iter().sum::<f64>() / n as f64,
    })
}

/// Weighted least squares of y = a·x + b.
fn solve(points: &[(f64, f64, usize)], w: &[f64]) -> Result<(f64, f64)> {
    let (mut sw, mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (&(x, y, _), &wi) in points.iter().zip(w) {
        sw += wi;
        sx += wi * x;
        sy += wi * y;
        sxx += wi * x * x;
        sxy += wi * x * y;
    }
    let det = sw * sxx - sx * sx;
    if !(det.is_finite() && det > 1e-12 * sw * sxx.max(1e-300)) {
        return Err(Error::invalid(
            "photon transfer",
            "the levels' means are (nearly) all the same: capture flats at several exposures",
        ));
    }
    Ok(((sw * sxy - sx * sy) / det, (sxx * sy - sx * sxy) / det))
}

/// The median (the mean of the two middle values for an even count; 0 for none).
pub(super) fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n == 0 {
        return 0.0;
    }
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

/// Student's t at 97.5 % for `dof` degrees of freedom (two-sided 95 %).
fn student_t_975(dof: usize) -> f64 {
    const T: [f64; 30] = [
        12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160,
        2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056,
        2.052, 2.048, 2.045, 2.042,
    ];
    match dof {
        0 => f64::INFINITY,
        d if d <= 30 => T[d - 1],
        // Past 30: the normal quantile with the first term of the expansion in 1/dof.
        d => 1.960 + 2.4 / d as f64,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_a_line_and_its_intervals_hold_it() {
        // Exact points on σ² = 0.2·μ + 10, with noise of the size a variance of 5 000
        // degrees of freedom has, and one wild point the robust weights set aside.
        let mut pts: Vec<(f64, f64, usize)> = (0..10)
            .map(|i| {
                let x = 10.0 + 20.0 * i as f64;
                let y = 0.2 * x + 10.0;
                let wiggle = if i % 2 == 0 { 1.0 } else { -1.0 } * y * (2.0f64 / 5000.0).sqrt();
                (x, y + wiggle, 5000)
            })
            .collect();
        pts[4].1 *= 1.5;
        let f = fit_line(&pts).unwrap();
        assert!(
            (f.a - 0.2).abs() < 0.01 && (f.b - 10.0).abs() < 0.5,
            "{f:?}"
        );
        assert!(f.a_ci[0] < 0.2 && 0.2 < f.a_ci[1], "{f:?}");
        assert!(f.b_ci[0] < 10.0 && 10.0 < f.b_ci[1], "{f:?}");
        assert!(f.inlier_share < 1.0);
        assert!(fit_line(&pts[..2]).is_err());
        let same = [(5.0, 11.0, 100), (5.0, 11.2, 100), (5.0, 10.9, 100)];
        let e = fit_line(&same).unwrap_err().to_string();
        assert!(e.contains("several exposures"), "{e}");
    }
}
