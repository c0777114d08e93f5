//! Gamma (Eq. S4) and 8-bit quantisation fused into one exact table lookup: the output level of
//! y is round(255 · y^γ), found by comparing y with the precomputed level boundaries
//! y_k = ((k − ½)/255)^(1/γ) (in f64) instead of calling `powf` per pixel.

use rayon::prelude::*;

use crate::types::Image;

/// Number of uniform bins over [0, 1] used to find the candidate levels of a value.
const BINS: usize = 4096;

/// The fused curve for one γ at 8 bits.
pub struct GammaQuantizer {
    /// Level boundaries: value y reaches level k (1..=255) when y ≥ thresholds[k − 1].
    thresholds: Vec<f64>,
    /// Per bin, the levels at its two ends.
    bins: Vec<(u8, u8)>,
}

impl GammaQuantizer {
    /// Tables for exponent `gamma` (> 0, finite).
    pub fn new(gamma: f32) -> Self {
        let inv = 1.0 / gamma as f64;
        let thresholds: Vec<f64> = (1..=255)
            .map(|k| ((k as f64 - 0.5) / 255.0).powf(inv))
            .collect();
        let level = |y: f64| thresholds.partition_point(|&t| t <= y) as u8;
        let bins = (0..BINS)
            .map(|i| {
                (
                    level(i as f64 / BINS as f64),
                    level((i + 1) as f64 / BINS as f64),
                )
            })
            .collect();
        Self { thresholds, bins }
    }

    /// The level (0..=255) of one value; NaN and values below 0 give 0, above 1 give 255.
    #[inline]
    pub fn level(&self, y: f32) -> u8 {
        // NaN fails every comparison, so it lands here with the negatives.
        if y.is_nan() || y <= 0.0 {
            return 0;
        }
        if y >= 1.0 {
            return 255;
        }
        let (lo, hi) = self.bins[((y * BINS as f32) as usize).min(BINS - 1)];
        if lo == hi {
            return lo;
        }
        let y = y as f64;
        if hi == lo + 1 {
            return if y >= self.thresholds[lo as usize] {
                hi
            } else {
                lo
            };
        }
        // Steep curves (small γ) put several boundaries in one bin: search them.
        lo + self.thresholds[lo as usize..hi as usize].partition_point(|&t| t <= y) as u8
    }

    /// Clamps, applies the curve and quantises every sample in place (values k/255).
    pub fn apply(&self, image: &mut Image) {
        image.data_mut().par_chunks_mut(4096).for_each(|chunk| {
            for v in chunk {
                *v = self.level(*v) as f32 / 255.0;
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_the_f64_curve_exactly() {
        for gamma in [1.7f32, 1.0, 0.3, 2.9, 1e-3, 40.0] {
            let q = GammaQuantizer::new(gamma);
            for i in 0..=200_000 {
                let y = i as f32 / 200_000.0;
                let exact = (255.0 * (y as f64).powf(gamma as f64)).round();
                // Only a value within rounding distance of a boundary may differ.
                let got = q.level(y) as f64;
                if got != exact {
                    let boundary = ((got.max(exact) - 0.5) / 255.0).powf(1.0 / gamma as f64);
                    assert!(
                        ((y as f64) - boundary).abs() < 1e-7,
                        "γ {gamma}, y {y}: {got} vs {exact}"
                    );
                }
            }
            assert_eq!(q.level(-0.3), 0);
            assert_eq!(q.level(f32::NAN), 0);
            assert_eq!(q.level(7.0), 255);
        }
    }
}
