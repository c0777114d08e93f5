//! The camera's noise level function (Eq. S3's σ² = a·y + b, seen through the gamma of Eq.
//! S4 and whatever a real camera adds): each channel's temporal spread as a function of its
//! 8-bit level, measured on the still background (Liu et al. 2008, "Automatic estimation
//! and removal of noise from a single image"), so that a difference from the background can
//! be weighed in the noise of its pixel's brightness. Dark parts of a frame are quieter than
//! bright ones; a mover over them differs by fewer levels but as surely.

use crate::track::robust;

/// Width of a level bin (8-bit levels): 16 bins over 0–255.
const BIN: f32 = 16.0;
const BINS: usize = 16;
/// Fewest samples a bin needs for its own spread; fewer take their nearest measured bin's.
const MIN_SAMPLES: usize = 5;

/// σ per channel and level bin (8-bit levels), floored.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct NoiseLevel {
    sigma: [[f32; BINS]; 3],
}

impl NoiseLevel {
    /// From samples `(channel, level, median absolute deviation)` of pixels of the still
    /// background (their temporal median and the MAD of their samples about it): per channel
    /// and bin, 1.4826 × the median of the bin's MADs (robust to the few samples a mover
    /// crossed), bins with fewer than `MIN_SAMPLES` taking their nearest measured bin's, a
    /// channel with none the floor; never below `floor`.
    pub(crate) fn fit(samples: impl IntoIterator<Item = (usize, f32, f32)>, floor: f32) -> Self {
        let mut bins: Vec<Vec<f32>> = vec![Vec::new(); 3 * BINS];
        for (c, level, mad) in samples {
            if c < 3 && level.is_finite() && mad.is_finite() {
                bins[c * BINS + bin(level)].push(mad);
            }
        }
        let mut sigma = [[floor; BINS]; 3];
        for (c, row) in sigma.iter_mut().enumerate() {
            let measured: Vec<Option<f32>> = (0..BINS)
                .map(|i| {
                    let v = &mut bins[c * BINS + i];
                    if v.len() >= MIN_SAMPLES {
                        robust::median(v).map(robust::sigma_f32)
                    } else {
                        None
                    }
                })
                .collect();
            for (i, s) in row.iter_mut().enumerate() {
                let nearest = (0..BINS)
                    .filter_map(|j| measured[j].map(|m| (i.abs_diff(j), m)))
                    .min_by_key(|&(d, _)| d);
                if let Some((_, m)) = nearest {
                    *s = m.max(floor);
                }
            }
        }
        Self { sigma }
    }

    /// σ of channel `c` at `level` (8-bit), linear between the bins' centres.
    pub(crate) fn sigma(&self, c: usize, level: f32) -> f32 {
        let row = &self.sigma[c.min(2)];
        let t = (level / BIN - 0.5).clamp(0.0, (BINS - 1) as f32);
        let i = (t.floor() as usize).min(BINS - 2);
        let f = t - i as f32;
        row[i] * (1.0 - f) + row[i + 1] * f
    }
}

fn bin(level: f32) -> usize {
    ((level / BIN).max(0.0) as usize).min(BINS - 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_spread_follows_the_level_and_ignores_a_few_crossings() {
        // Green quiet in the dark (MAD 1.35 → σ 2) and noisy in the bright (MAD 8.1 → σ 12);
        // a tenth of the bright samples crossed by a mover (MAD 60).
        let mut s = Vec::new();
        for i in 0..50 {
            s.push((1, 20.0 + (i % 8) as f32, 1.349));
            s.push((
                1,
                200.0 + (i % 8) as f32,
                if i % 10 == 0 { 60.0 } else { 8.094 },
            ));
        }
        let nl = NoiseLevel::fit(s, 1.0);
        assert!(
            (nl.sigma(1, 24.0) - 2.0).abs() < 0.01,
            "{}",
            nl.sigma(1, 24.0)
        );
        assert!(
            (nl.sigma(1, 200.0) - 12.0).abs() < 0.01,
            "{}",
            nl.sigma(1, 200.0)
        );
        // Between them, linear in the level; beyond them, their nearest bin's.
        let mid = nl.sigma(1, 112.0);
        assert!(mid > 2.0 && mid < 12.0, "{mid}");
        assert!((nl.sigma(1, 0.0) - 2.0).abs() < 0.01);
        assert!((nl.sigma(1, 255.0) - 12.0).abs() < 0.01);
        // A channel with no samples, and a quiet one, stand at the floor.
        assert_eq!(nl.sigma(0, 100.0), 1.0);
        let flat = NoiseLevel::fit((0..20).map(|_| (2, 90.0, 0.0)), 1.5);
        assert_eq!(flat.sigma(2, 90.0), 1.5);
    }
}
