//! The change test of a detection (Note S13's region of interest, made robust to the jitter
//! of an estimated flow): a pixel can only move where the frames changed. The temporal
//! difference |I₁ − I₂ ∘ background| (the background's motion compensated, so a flying PINS
//! works too) is averaged over a `window × window` box against sensor noise and compared with
//! the frame's own noise floor, its median plus `k` robust standard deviations (1.4826 × MAD).
//! Spurious flow on a still background explains no change and fails the test; a slow mover
//! whose flow is under the frame's flow-jitter floor still passes it.

use super::background::GlobalMotion;
use super::noise_floor::robust_floor;
use super::photometric::GreyPair;
use crate::imaging::box_filter::box_mean;

/// Which pixels changed between the two frames, and the level used.
#[derive(Clone, Debug, PartialEq)]
pub struct ChangeMask {
    /// `[H, W]`: the box-averaged difference exceeds `level`.
    pub mask: Vec<bool>,
    /// The noise floor (grey levels in [0, 1]): median + k · 1.4826 · MAD, at least
    /// `min_level`.
    pub level: f64,
}

/// The change mask of `pair` with `null` (the background's motion) compensated.
pub fn change_mask(
    pair: &GreyPair,
    null: &GlobalMotion,
    window: usize,
    k: f64,
    min_level: f64,
) -> ChangeMask {
    let (w, h) = (pair.width, pair.height);
    let r = window / 2;
    let (averaged, counts) = box_mean(&pair.difference(null), w, h, r);
    let (med, level) = robust_floor(averaged.clone(), k)
        .map_or((0.0, f64::INFINITY), |(med, floor)| {
            (med, floor.max(min_level))
        });
    // A box clipped by the border averages fewer pixels and spreads more: its deviation from
    // the median is scaled by √(n / n_full) before the comparison.
    let full = ((2 * r + 1) * (2 * r + 1)) as f64;
    ChangeMask {
        mask: averaged
            .iter()
            .zip(&counts)
            .map(|(&v, &n)| {
                v.is_finite() && med + (v as f64 - med) * (n as f64 / full).sqrt() > level
            })
            .collect(),
        level,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::types::Image;
    use rand_distr::{Distribution, StandardNormal};

    /// Noisy still frames with a textured 12×12 square moved 3 px right in frame 2 (the
    /// change reaches the box radius, 3 px, beyond the square's two positions).
    fn noisy_frames(seed: u64, sigma: f32) -> (Image, Image) {
        let (w, h) = (80, 60);
        let mut rng = crate::rng::stream(seed, &[0]);
        let tex = |x: f32, y: f32| 0.3 + 0.05 * (x * 0.3).sin() * (y * 0.2).cos();
        let obj = |x: f32, y: f32| 0.5 + 0.2 * (x * 1.1).sin() * (y * 0.9).cos();
        let (mut a, mut b) = (Image::zeros(1, h, w), Image::zeros(1, h, w));
        for y in 0..h {
            for x in 0..w {
                let (xf, yf) = (x as f32, y as f32);
                let in_a = (30.0..42.0).contains(&xf) && (20.0..32.0).contains(&yf);
                let in_b = (33.0..45.0).contains(&xf) && (20.0..32.0).contains(&yf);
                let va = if in_a { obj(xf, yf) } else { tex(xf, yf) };
                let vb = if in_b { obj(xf - 3.0, yf) } else { tex(xf, yf) };
                a.set(
                    0,
                    y,
                    x,
                    va + sigma * Distribution::<f32>::sample(&StandardNormal, &mut rng),
                );
                b.set(
                    0,
                    y,
                    x,
                    vb + sigma * Distribution::<f32>::sample(&StandardNormal, &mut rng),
                );
            }
        }
        (a, b)
    }

    #[test]
    fn the_mover_changes_and_the_noisy_still_background_does_not() {
        for seed in [1, 2, 3] {
            let (a, b) = noisy_frames(seed, 0.02);
            let pair = GreyPair::new(&a, &b).unwrap();
            let c = change_mask(&pair, &GlobalMotion::zero(), 7, 4.0, 1e-4);
            let w = 80;
            let inside = (22..30)
                .flat_map(|y| (32..42).map(move |x| y * w + x))
                .filter(|&p| c.mask[p])
                .count();
            let outside = c
                .mask
                .iter()
                .enumerate()
                .filter(|&(p, &m)| {
                    let (x, y) = (p % w, p / w);
                    m && !((16..36).contains(&y) && (26..49).contains(&x))
                })
                .count();
            assert!(
                inside >= 75,
                "seed {seed}: {inside} of 80 changed pixels found"
            );
            // A stray pixel may pass at 4 robust standard deviations; never a region's worth.
            assert!(
                outside < 10,
                "seed {seed}: {outside} changes on the still background"
            );
            assert!(c.level > 0.0 && c.level < 0.1, "level {}", c.level);
        }
    }

    #[test]
    fn identical_frames_change_nowhere() {
        let (a, _) = noisy_frames(4, 0.0);
        let pair = GreyPair::new(&a, &a).unwrap();
        let c = change_mask(&pair, &GlobalMotion::zero(), 7, 4.0, 1e-4);
        assert!(c.mask.iter().all(|m| !m));
        assert_eq!(c.level, 1e-4);
    }
}
