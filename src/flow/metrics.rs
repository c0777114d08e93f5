//! Flow accuracy (Table S4): end-point error, angular error (Baker et al. 2011: the angle between
//! (u, v, 1) and (u_gt, v_gt, 1)), and the fractions within 1, 3 and 5 px — accumulated as sums
//! over valid pixels, so that a dataset's score is a mean over pixels, not a mean of means.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::types::Flow;

/// Running sums over valid pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FlowErrorSums {
    pub pixels: u64,
    pub epe: f64,
    pub ae_deg: f64,
    pub within_1: u64,
    pub within_3: u64,
    pub within_5: u64,
}

/// Dataset-level scores.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FlowScores {
    pub epe: f64,
    pub ae_deg: f64,
    pub px1: f64,
    pub px3: f64,
    pub px5: f64,
    pub pixels: u64,
}

/// End-point error of one vector.
#[inline]
pub fn endpoint_error(u: f64, v: f64, ug: f64, vg: f64) -> f64 {
    ((u - ug).powi(2) + (v - vg).powi(2)).sqrt()
}

/// Angular error in degrees between (u, v, 1) and (ug, vg, 1); the cosine is clamped so that
/// rounding cannot push it out of [−1, 1] and return NaN.
#[inline]
pub fn angular_error_deg(u: f64, v: f64, ug: f64, vg: f64) -> f64 {
    let num = u * ug + v * vg + 1.0;
    let den = ((u * u + v * v + 1.0) * (ug * ug + vg * vg + 1.0)).sqrt();
    (num / den).clamp(-1.0, 1.0).acos().to_degrees()
}

impl FlowErrorSums {
    /// Adds the pixels of `pred` against `gt` where `valid` (if given) is true and the ground
    /// truth is finite. Sizes must match.
    pub fn add(&mut self, pred: &Flow, gt: &Flow, valid: Option<&[bool]>) -> Result<()> {
        if (pred.height(), pred.width()) != (gt.height(), gt.width()) {
            return Err(Error::shape(
                "predicted flow",
                format!("{}x{} (the ground truth)", gt.width(), gt.height()),
                format!("{}x{}", pred.width(), pred.height()),
            ));
        }
        if let Some(m) = valid
            && m.len() != gt.u().len()
        {
            return Err(Error::shape("validity mask", gt.u().len(), m.len()));
        }
        let (pu, pv, gu, gv) = (pred.u(), pred.v(), gt.u(), gt.v());
        for i in 0..gu.len() {
            if valid.is_some_and(|m| !m[i]) || !(gu[i].is_finite() && gv[i].is_finite()) {
                continue;
            }
            let (u, v, ug, vg) = (pu[i] as f64, pv[i] as f64, gu[i] as f64, gv[i] as f64);
            if !(u.is_finite() && v.is_finite()) {
                return Err(Error::invalid(
                    "predicted flow",
                    format!("non-finite vector at pixel {i}"),
                ));
            }
            let e = endpoint_error(u, v, ug, vg);
            self.pixels += 1;
            self.epe += e;
            self.ae_deg += angular_error_deg(u, v, ug, vg);
            self.within_1 += (e < 1.0) as u64;
            self.within_3 += (e < 3.0) as u64;
            self.within_5 += (e < 5.0) as u64;
        }
        Ok(())
    }

    /// Adds another set of sums.
    pub fn merge(&mut self, o: &FlowErrorSums) {
        self.pixels += o.pixels;
        self.epe += o.epe;
        self.ae_deg += o.ae_deg;
        self.within_1 += o.within_1;
        self.within_3 += o.within_3;
        self.within_5 += o.within_5;
    }

    /// Means over all pixels added (zeros when none were).
    pub fn scores(&self) -> FlowScores {
        let n = self.pixels.max(1) as f64;
        FlowScores {
            epe: self.epe / n,
            ae_deg: self.ae_deg / n,
            px1: self.within_1 as f64 / n,
            px3: self.within_3 as f64 / n,
            px5: self.within_5 as f64 / n,
            pixels: self.pixels,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_errors() {
        assert_eq!(endpoint_error(3.0, 4.0, 0.0, 0.0), 5.0);
        assert!(angular_error_deg(2.0, -1.0, 2.0, -1.0).abs() < 1e-6);
        // (1,0,1) against (0,0,1): 45°.
        assert!((angular_error_deg(1.0, 0.0, 0.0, 0.0) - 45.0).abs() < 1e-9);
        // Huge, nearly parallel vectors: no NaN from rounding.
        assert!(angular_error_deg(1e8, 1e8, 1e8, 1e8).is_finite());
    }

    #[test]
    fn sums_are_over_valid_pixels() {
        let gt = Flow::from_vec(1, 3, vec![0.0, 0.0, f32::NAN, 0.0, 0.0, 0.0]).unwrap();
        let pred = Flow::from_vec(1, 3, vec![0.5, 4.0, 9.0, 0.0, 0.0, 0.0]).unwrap();
        let mut s = FlowErrorSums::default();
        s.add(&pred, &gt, None).unwrap();
        let sc = s.scores();
        assert_eq!(sc.pixels, 2);
        assert!((sc.epe - 2.25).abs() < 1e-12);
        assert_eq!((sc.px1, sc.px3, sc.px5), (0.5, 0.5, 1.0));
        let mut masked = FlowErrorSums::default();
        masked.add(&pred, &gt, Some(&[true, false, true])).unwrap();
        assert_eq!(masked.scores().pixels, 1);
        assert!(s.add(&Flow::zeros(2, 2), &gt, None).is_err());
    }
}
