//! Bivariate polynomial least squares for the distortion maps of Note S3: f(x, y) = Σ c_ij ·
//! x^i · y^j over i + j ≤ n, on centred and scaled coordinates, solved by Householder QR in
//! f64 (never the normal equations, whose condition number is the square).

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// A fitted 2-D polynomial with its coordinate normalisation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Poly2 {
    pub order: usize,
    /// (x − centre) / scale, per axis.
    pub centre: [f64; 2],
    pub scale: [f64; 2],
    pub coefficients: Vec<f64>,
}

/// Highest polynomial order a calibration may hold.
pub const MAX_ORDER: usize = 10;

/// Number of monomials of total degree ≤ `order`.
pub fn terms(order: usize) -> usize {
    (order + 1) * (order + 2) / 2
}

fn monomials(order: usize, x: f64, y: f64, out: &mut Vec<f64>) {
    out.clear();
    for d in 0..=order {
        for j in 0..=d {
            out.push(x.powi((d - j) as i32) * y.powi(j as i32));
        }
    }
}

impl Poly2 {
    /// Least-squares fit of `values` at `points`. Fewer points than coefficients, or points that
    /// do not determine the polynomial (rank deficiency), are errors.
    pub fn fit(points: &[(f64, f64)], values: &[f64], order: usize) -> Result<Self> {
        let m = terms(order);
        if points.len() != values.len() {
            return Err(Error::shape(
                "polynomial fit values",
                points.len(),
                values.len(),
            ));
        }
        if points.len() < m {
            return Err(Error::invalid(
                "polynomial fit",
                format!(
                    "order {order} needs at least {m} points, got {}",
                    points.len()
                ),
            ));
        }
        let n = points.len() as f64;
        let centre = [
            points.iter().map(|p| p.0).sum::<f64>() / n,
            points.iter().map(|p| p.1).sum::<f64>() / n,
        ];
        let scale = [
            points
                .iter()
                .map(|p| (p.0 - centre[0]).abs())
                .fold(0.0, f64::max)
                .max(1e-12),
            points
                .iter()
                .map(|p| (p.1 - centre[1]).abs())
                .fold(0.0, f64::max)
                .max(1e-12),
        ];
        let rows = points.len();
        // Design matrix, column-major for the Householder sweeps.
        let mut a = vec![0.0; rows * m];
        let mut row = Vec::with_capacity(m);
        for (r, p) in points.iter().enumerate() {
            monomials(
                order,
                (p.0 - centre[0]) / scale[0],
                (p.1 - centre[1]) / scale[1],
                &mut row,
            );
            for (c, v) in row.iter().enumerate() {
                a[c * rows + r] = *v;
            }
        }
        let mut b = values.to_vec();
        for k in 0..m {
            let col = &a[k * rows..(k + 1) * rows];
            let norm = col[k..].iter().map(|v| v * v).sum::<f64>().sqrt();
            if norm < 1e-12 * (rows as f64).sqrt() {
                return Err(Error::invalid(
                    "polynomial fit",
                    format!(
                        "the points do not determine an order-{order} polynomial (rank deficient)"
                    ),
                ));
            }
            let alpha = if col[k] > 0.0 { -norm } else { norm };
            let mut v: Vec<f64> = col[k..].to_vec();
            v[0] -= alpha;
            let vn2: f64 = v.iter().map(|x| x * x).sum();
            if vn2 == 0.0 {
                continue;
            }
            for c in k..m {
                let colc = &mut a[c * rows + k..(c + 1) * rows];
                let dot: f64 = v.iter().zip(colc.iter()).map(|(p, q)| p * q).sum();
                let f = 2.0 * dot / vn2;
                for (q, p) in colc.iter_mut().zip(&v) {
                    *q -= f * p;
                }
            }
            let dot: f64 = v.iter().zip(&b[k..]).map(|(p, q)| p * q).sum();
            let f = 2.0 * dot / vn2;
            for (q, p) in b[k..].iter_mut().zip(&v) {
                *q -= f * p;
            }
        }
        // Back substitution on R (upper m×m).
        let mut coefficients = vec![0.0; m];
        for k in (0..m).rev() {
            let mut s = b[k];
            for c in k + 1..m {
                s -= a[c * rows + k] * coefficients[c];
            }
            let d = a[k * rows + k];
            if d.abs() < 1e-12 {
                return Err(Error::invalid("polynomial fit", "rank deficient design"));
            }
            coefficients[k] = s / d;
        }
        Ok(Self {
            order,
            centre,
            scale,
            coefficients,
        })
    }

    /// Evaluates at `(x, y)`.
    /// Checks a polynomial read from a file: an order up to [`MAX_ORDER`], exactly
    /// `terms(order)` coefficients, finite numbers and non-zero scales. `what` names it.
    pub fn validate(&self, what: &str) -> Result<()> {
        if self.order > MAX_ORDER {
            return Err(Error::invalid(
                what,
                format!("order {} is above {MAX_ORDER}", self.order),
            ));
        }
        if self.coefficients.len() != terms(self.order) {
            return Err(Error::invalid(
                what,
                format!(
                    "order {} needs {} coefficients, found {}",
                    self.order,
                    terms(self.order),
                    self.coefficients.len()
                ),
            ));
        }
        let finite = self
            .coefficients
            .iter()
            .chain(&self.centre)
            .all(|v| v.is_finite());
        if !finite || self.scale.iter().any(|s| !s.is_finite() || *s == 0.0) {
            return Err(Error::invalid(
                what,
                "coefficients, centre and scale must be finite and the scales non-zero",
            ));
        }
        Ok(())
    }

    pub fn eval(&self, x: f64, y: f64) -> f64 {
        let (u, v) = (
            (x - self.centre[0]) / self.scale[0],
            (y - self.centre[1]) / self.scale[1],
        );
        let mut s = 0.0;
        let mut k = 0;
        for d in 0..=self.order {
            for j in 0..=d {
                s += self.coefficients[k] * u.powi((d - j) as i32) * v.powi(j as i32);
                k += 1;
            }
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_polynomial_from_a_file_is_checked() {
        let pts: Vec<(f64, f64)> = (0..30).map(|i| ((i % 6) as f64, (i / 6) as f64)).collect();
        let vals: Vec<f64> = pts.iter().map(|p| p.0 + 2.0 * p.1).collect();
        let p = Poly2::fit(&pts, &vals, 2).unwrap();
        assert!(p.validate("fx").is_ok());
        let mut q = p.clone();
        q.order = 3;
        assert!(
            q.validate("fx")
                .unwrap_err()
                .to_string()
                .contains("10 coefficients")
        );
        let mut q = p.clone();
        q.scale[1] = 0.0;
        assert!(q.validate("fx").is_err());
        let mut q = p.clone();
        q.coefficients[0] = f64::NAN;
        assert!(q.validate("fx").is_err());
        let mut q = p;
        q.order = 1000;
        assert!(q.validate("fx").is_err());
    }

    #[test]
    fn recovers_a_polynomial_and_rejects_degenerate_fits() {
        let f = |x: f64, y: f64| {
            3.0 + 0.5 * x - 2.0 * y + 1e-3 * x * y + 2e-4 * x * x - 1e-6 * y * y * y
        };
        let pts: Vec<(f64, f64)> = (0..100)
            .map(|i| {
                (
                    1000.0 + (i % 10) as f64 * 37.0,
                    500.0 + (i / 10) as f64 * 29.0,
                )
            })
            .collect();
        let vals: Vec<f64> = pts.iter().map(|p| f(p.0, p.1)).collect();
        let p = Poly2::fit(&pts, &vals, 3).unwrap();
        assert!((p.eval(1111.0, 600.0) - f(1111.0, 600.0)).abs() < 1e-8);
        assert!(
            Poly2::fit(&pts[..5], &vals[..5], 3).is_err(),
            "fewer points than coefficients"
        );
        let line: Vec<(f64, f64)> = (0..20).map(|i| (i as f64, 2.0 * i as f64)).collect();
        assert!(
            Poly2::fit(&line, &[1.0; 20], 2).is_err(),
            "collinear points"
        );
    }
}
