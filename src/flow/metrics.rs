//! Flow accuracy (Table S4): end-point error, angular error (Baker et al. 2011: the angle between
//! (u, v, 1) and (u_gt, v_gt, 1)), and the fractions within 1, 3 and 5 px — accumulated as sums
//! over valid pixels, so that a dataset's score is a mean over pixels, not a mean of means; and
//! the EPE by ground-truth speed in the MPI-Sintel benchmark's classes (Butler et al. 2012:
//! s0-10, s10-40, s40+), which tells where an error lies: small motions or large ones.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::types::Flow;

/// The MPI-Sintel benchmark's speed classes: a pixel's ground-truth speed is below 10 px
/// (s0-10), from 10 to below 40 (s10-40), or 40 px or more (s40+).
pub const SPEED_CLASS_EDGES: [f64; 2] = [10.0, 40.0];

/// The names of the classes of [`SPEED_CLASS_EDGES`], as the Sintel benchmark gives them.
pub const SPEED_CLASS_NAMES: [&str; 3] = ["s0-10", "s10-40", "s40+"];

/// The speed class of a ground-truth vector of length `speed` (an index into
/// [`SPEED_CLASS_NAMES`]).
#[inline]
pub fn speed_class(speed: f64) -> usize {
    SPEED_CLASS_EDGES.iter().filter(|&&e| speed >= e).count()
}

/// EPE by ground-truth speed class ([`SPEED_CLASS_NAMES`]): each class's pixel count and mean
/// end-point error over them (0 where a class has none; [`EpeBySpeed::get`] tells them apart).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct EpeBySpeed {
    pub pixels: [u64; 3],
    pub epe: [f64; 3],
}

impl EpeBySpeed {
    /// Class `c`'s mean EPE, or `None` where no pixel moves at its speeds.
    pub fn get(&self, c: usize) -> Option<f64> {
        (self.pixels[c] > 0).then_some(self.epe[c])
    }

    /// Pools `parts` by their pixels (a mean over all their pixels of each class).
    pub fn pooled<'a>(parts: impl IntoIterator<Item = &'a EpeBySpeed>) -> EpeBySpeed {
        let mut out = EpeBySpeed::default();
        for p in parts {
            for c in 0..3 {
                out.pixels[c] += p.pixels[c];
                out.epe[c] += p.epe[c] * p.pixels[c] as f64;
            }
        }
        for c in 0..3 {
            out.epe[c] /= out.pixels[c].max(1) as f64;
        }
        out
    }

    /// The mean of `parts`' class means, each class over the parts that have pixels in it
    /// (every set weighs the same, as the benchmark's "mean of sets"); pixels are summed.
    pub fn mean_of<'a>(parts: impl IntoIterator<Item = &'a EpeBySpeed>) -> EpeBySpeed {
        let (mut out, mut sets) = (EpeBySpeed::default(), [0usize; 3]);
        for p in parts {
            for (c, n) in sets.iter_mut().enumerate() {
                if p.pixels[c] > 0 {
                    out.pixels[c] += p.pixels[c];
                    out.epe[c] += p.epe[c];
                    *n += 1;
                }
            }
        }
        for (e, n) in out.epe.iter_mut().zip(sets) {
            *e /= n.max(1) as f64;
        }
        out
    }
}

/// Running sums over valid pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FlowErrorSums {
    pub pixels: u64,
    pub epe: f64,
    pub ae_deg: f64,
    pub within_1: u64,
    pub within_3: u64,
    pub within_5: u64,
    /// Pixels and summed EPE per speed class ([`SPEED_CLASS_NAMES`]).
    #[serde(default)]
    pub class_pixels: [u64; 3],
    #[serde(default)]
    pub class_epe: [f64; 3],
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
    /// The EPE by ground-truth speed class.
    #[serde(default)]
    pub by_speed: EpeBySpeed,
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
            let c = speed_class(ug.hypot(vg));
            self.class_pixels[c] += 1;
            self.class_epe[c] += e;
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
        for c in 0..3 {
            self.class_pixels[c] += o.class_pixels[c];
            self.class_epe[c] += o.class_epe[c];
        }
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
            by_speed: EpeBySpeed {
                pixels: self.class_pixels,
                epe: std::array::from_fn(|c| {
                    self.class_epe[c] / self.class_pixels[c].max(1) as f64
                }),
            },
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

    #[test]
    fn speed_classes_are_sintels() {
        // Below 10, from 10 to below 40, 40 and more: the edges belong to the faster class.
        let classes: Vec<usize> = [0.0, 9.999, 10.0, 39.9, 40.0, 500.0]
            .into_iter()
            .map(speed_class)
            .collect();
        assert_eq!(classes, [0, 0, 1, 1, 2, 2]);
        // One pixel per class (speeds 3, 20 and 50 along x), each 1, 2 and 4 px off; a fourth
        // pixel in the middle class 6 px off.
        let gt = Flow::from_vec(1, 4, vec![3.0, 20.0, 50.0, 0.0, 0.0, 0.0, 0.0, 30.0]).unwrap();
        let pred = Flow::from_vec(1, 4, vec![4.0, 22.0, 46.0, 0.0, 0.0, 0.0, 0.0, 24.0]).unwrap();
        let mut s = FlowErrorSums::default();
        s.add(&pred, &gt, None).unwrap();
        let b = s.scores().by_speed;
        assert_eq!(b.pixels, [1, 2, 1]);
        assert_eq!(
            [b.get(0), b.get(1), b.get(2)],
            [Some(1.0), Some(4.0), Some(4.0)]
        );
        // The classes add up to the whole.
        let whole: f64 = (0..3).map(|c| b.epe[c] * b.pixels[c] as f64).sum();
        assert!((whole / 4.0 - s.scores().epe).abs() < 1e-12);
        // A set without fast pixels has no s40+ score; pooling weighs by pixels.
        let mut slow = FlowErrorSums::default();
        slow.add(&Flow::zeros(1, 1), &Flow::zeros(1, 1), None)
            .unwrap();
        let slow = slow.scores().by_speed;
        assert_eq!((slow.get(0), slow.get(2)), (Some(0.0), None));
        let pooled = EpeBySpeed::pooled([&b, &slow]);
        assert_eq!(pooled.pixels, [2, 2, 1]);
        assert_eq!([pooled.get(0), pooled.get(2)], [Some(0.5), Some(4.0)]);
        let mean = EpeBySpeed::mean_of([&b, &slow]);
        assert_eq!(
            [mean.get(0), mean.get(1), mean.get(2)],
            [Some(0.5), Some(4.0), Some(4.0)]
        );
        // Merged sums give the same classes as one pass.
        let mut m = FlowErrorSums::default();
        m.merge(&s);
        assert_eq!(m.scores().by_speed, b);
    }
}
