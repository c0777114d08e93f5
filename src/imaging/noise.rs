//! Sensor noise (Note S4): the heteroscedastic Gaussian of Eq. S3, z ~ N(y, a·y + b) in 8-bit
//! digital numbers, or the exact Poisson shot noise plus Gaussian read noise of Eqs. S1–S2.

use rand::SeedableRng;
use rand_distr::{Distribution, Poisson, StandardNormal};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::rng;
use crate::types::Image;

/// Digital numbers per unit intensity: the noise parameters are given for an 8-bit sensor.
pub const DN_SCALE: f32 = 255.0;

/// Which distribution draws the noisy value.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NoiseModel {
    /// Eq. S3: one Gaussian with variance a·y + b (DN²).
    #[default]
    Gaussian,
    /// Eqs. S1–S2: a·Poisson(y / a) photon shot noise plus N(0, b) read noise; same mean and
    /// variance as Eq. S3, but skewed at low counts as real photon noise is.
    PoissonGaussian,
}

/// Noise parameters: `a` (shot, DN per DN) and `b` (read, DN²).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NoiseConfig {
    pub model: NoiseModel,
    pub a: f32,
    pub b: f32,
}

impl Default for NoiseConfig {
    /// The paper's choice (Note S4): a = 0.2, b = 10.
    fn default() -> Self {
        Self {
            model: NoiseModel::Gaussian,
            a: 0.2,
            b: 10.0,
        }
    }
}

impl NoiseConfig {
    /// Checks that a and b are finite and non-negative.
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [("noise.a", self.a), ("noise.b", self.b)] {
            if !v.is_finite() || v < 0.0 {
                return Err(Error::invalid(
                    name,
                    format!("must be finite and >= 0, got {v}"),
                ));
            }
        }
        Ok(())
    }

    /// True when the stage would change nothing.
    pub fn is_identity(&self) -> bool {
        self.a == 0.0 && self.b == 0.0
    }

    /// Adds noise in place. Each (channel, row) draws from its own stream keyed by `seed`, so
    /// the result does not depend on the thread count. Values may leave [0, 1]: the clamp stage
    /// that follows handles that.
    pub fn apply(&self, image: &mut Image, seed: u64) {
        let (c, h, w) = image.shape();
        let (a, b) = (self.a, self.b);
        let read_sigma = b.sqrt();
        let model = self.model;
        image
            .data_mut()
            .par_chunks_mut(w)
            .enumerate()
            .for_each(|(row_index, row)| {
                let (ch, y) = (row_index / h, row_index % h);
                // Xoshiro256++: several times faster than ChaCha for the millions of draws a
                // frame needs, and statistically sound for simulation.
                let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(rng::derive(
                    seed,
                    &[rng::purpose::NOISE, ch as u64, y as u64],
                ));
                for v in row.iter_mut() {
                    // The signal cannot be negative; a clamp here keeps the variance valid.
                    let dn = v.max(0.0) * DN_SCALE;
                    let noisy = match model {
                        NoiseModel::Gaussian => {
                            let n: f32 = StandardNormal.sample(&mut rng);
                            dn + (a * dn + b).sqrt() * n
                        }
                        NoiseModel::PoissonGaussian => {
                            let shot = if a > 0.0 && dn > 0.0 {
                                let lambda = (dn / a) as f64;
                                match Poisson::new(lambda) {
                                    Ok(p) => (a as f64 * p.sample(&mut rng)) as f32,
                                    // Only for lambda beyond Poisson's range (> ~1e19): the
                                    // distribution is then Gaussian to any precision.
                                    Err(_) => {
                                        let n: f32 = StandardNormal.sample(&mut rng);
                                        dn + (a * dn).sqrt() * n
                                    }
                                }
                            } else {
                                dn
                            };
                            let n: f32 = StandardNormal.sample(&mut rng);
                            shot + read_sigma * n
                        }
                    };
                    *v = noisy / DN_SCALE;
                }
            });
        let _ = c;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stats(v: &[f32]) -> (f64, f64) {
        let n = v.len() as f64;
        let mean = v.iter().map(|&x| x as f64).sum::<f64>() / n;
        let var = v.iter().map(|&x| (x as f64 - mean).powi(2)).sum::<f64>() / n;
        (mean, var)
    }

    #[test]
    fn variance_matches_eq_s3_for_both_models() {
        for model in [NoiseModel::Gaussian, NoiseModel::PoissonGaussian] {
            for &level in &[0.05f32, 0.5] {
                let mut im = Image::filled(1, 256, 256, level);
                let cfg = NoiseConfig {
                    model,
                    a: 0.2,
                    b: 10.0,
                };
                cfg.apply(&mut im, 7);
                let (mean, var) = stats(im.data());
                let dn = level as f64 * 255.0;
                let expect_var = (0.2 * dn + 10.0) / (255.0f64 * 255.0);
                assert!((mean - level as f64).abs() < 3e-4, "{model:?} mean {mean}");
                assert!(
                    (var / expect_var - 1.0).abs() < 0.03,
                    "{model:?} var {var} vs {expect_var}"
                );
            }
        }
    }

    #[test]
    fn same_seed_same_noise_other_seed_other_noise() {
        let base = Image::filled(3, 16, 16, 0.3);
        let cfg = NoiseConfig::default();
        let (mut a, mut b, mut c) = (base.clone(), base.clone(), base.clone());
        cfg.apply(&mut a, 1);
        cfg.apply(&mut b, 1);
        cfg.apply(&mut c, 2);
        assert_eq!(a, b);
        assert_ne!(a, c);
    }

    #[test]
    fn extreme_parameters_stay_finite() {
        for (a, b) in [(1e6f32, 1e6f32), (0.0, 1e9), (1e-9, 0.0)] {
            for model in [NoiseModel::Gaussian, NoiseModel::PoissonGaussian] {
                let mut im = Image::filled(1, 8, 8, 1.0);
                im.set(0, 0, 0, 0.0);
                NoiseConfig { model, a, b }.apply(&mut im, 3);
                assert!(
                    im.data().iter().all(|v| v.is_finite()),
                    "{model:?} a={a} b={b}"
                );
            }
        }
        assert!(
            NoiseConfig {
                model: NoiseModel::Gaussian,
                a: -1.0,
                b: 0.0
            }
            .validate()
            .is_err()
        );
        assert!(
            NoiseConfig {
                model: NoiseModel::Gaussian,
                a: f32::NAN,
                b: 0.0
            }
            .validate()
            .is_err()
        );
    }
}
