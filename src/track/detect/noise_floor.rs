//! The robust noise floor of a frame (Note S13's threshold, made robust to an estimated
//! flow's jitter): the median of its values plus `k` robust standard deviations, 1.4826 × the
//! median absolute deviation, so a few movers do not raise it and a jittering background does.

use crate::track::robust;
use crate::types::Flow;

/// The median of the finite `values` and the floor median + `k` · 1.4826 · MAD; `None` when no
/// value is finite.
pub fn robust_floor(mut values: Vec<f32>, k: f64) -> Option<(f64, f64)> {
    values.retain(|v| v.is_finite());
    let (median, mad) = robust::upper_median_mad(&mut values)?;
    Some((median as f64, robust::floor(median as f64, mad as f64, k)))
}

/// Median flow magnitude plus `k` robust standard deviations; 0 when `k` is 0. Unknown
/// (non-finite) vectors are skipped, as in the region finder.
pub fn noise_floor(flow: &Flow, k: f64) -> f64 {
    if k <= 0.0 {
        return 0.0;
    }
    let m: Vec<f32> = flow
        .u()
        .iter()
        .zip(flow.v())
        .map(|(a, b)| a.hypot(*b))
        .collect();
    robust_floor(m, k).map_or(0.0, |(_, floor)| floor)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_noise_floor_ignores_a_few_movers_and_rises_with_jitter() {
        let mut f = Flow::zeros(20, 20);
        for i in 0..40 {
            f.set(i / 20, i % 20, 5.0, 0.0);
        }
        assert_eq!(
            noise_floor(&f, 3.0),
            0.0,
            "exact flow of a still background"
        );
        let mut noisy = Flow::zeros(20, 20);
        for y in 0..20 {
            for x in 0..20 {
                noisy.set(y, x, 1.0 + 0.5 * ((x * 7 + y * 3) % 5) as f32 / 4.0, 0.0);
            }
        }
        let t = noise_floor(&noisy, 3.0);
        assert!(t > 1.5 && t < 3.5, "{t}");
        assert_eq!(noise_floor(&noisy, 0.0), 0.0);
    }

    #[test]
    fn the_robust_floor_skips_unknown_values() {
        let (med, floor) = robust_floor(vec![1.0, f32::NAN, 2.0, 3.0, f32::INFINITY], 2.0).unwrap();
        assert_eq!(med, 2.0);
        assert!((floor - (2.0 + 2.0 * 1.4826)).abs() < 1e-9);
        assert!(robust_floor(vec![f32::NAN], 1.0).is_none());
    }
}
