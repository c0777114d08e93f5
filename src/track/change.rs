//! The change test of a detection (Note S13's region of interest, made robust to the jitter
//! of an estimated flow): a pixel can only move where the frames changed. The temporal
//! difference |I₁ − I₂ ∘ background| (the background's motion compensated, so a flying PINS
//! works too) is averaged over a `window × window` box against sensor noise and compared with
//! the frame's own noise floor, its median plus `k` robust standard deviations (1.4826 × MAD).
//! Spurious flow on a still background explains no change and fails the test; a slow mover
//! whose flow is under the frame's flow-jitter floor still passes it.

use super::background::GlobalMotion;
use super::photometric::GreyPair;

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
    let mut known: Vec<f32> = averaged.iter().copied().filter(|v| v.is_finite()).collect();
    let (level, med) = if known.is_empty() {
        (f64::INFINITY, 0.0)
    } else {
        let med = median(&mut known);
        let mut dev: Vec<f32> = known.iter().map(|v| (v - med).abs()).collect();
        let mad = median(&mut dev);
        (
            (med as f64 + k * 1.4826 * mad as f64).max(min_level),
            med as f64,
        )
    };
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

/// The mean of the known (finite) values in the `(2r + 1)²` box around each pixel of a
/// `[h, w]` plane, the box clipped at the border, and how many values it averaged; NaN where
/// the box holds no known value. Summed-area tables in f64, so the cost does not depend on
/// `r`.
fn box_mean(p: &[f32], w: usize, h: usize, r: usize) -> (Vec<f32>, Vec<u32>) {
    let stride = w + 1;
    let mut sum = vec![0.0f64; (h + 1) * stride];
    let mut count = vec![0u32; (h + 1) * stride];
    for y in 0..h {
        for x in 0..w {
            let v = p[y * w + x];
            let (s, c) = if v.is_finite() {
                (v as f64, 1)
            } else {
                (0.0, 0)
            };
            let i = (y + 1) * stride + x + 1;
            sum[i] = s + sum[i - 1] + sum[i - stride] - sum[i - stride - 1];
            count[i] = c + count[i - 1] + count[i - stride] - count[i - stride - 1];
        }
    }
    let mut out = vec![f32::NAN; w * h];
    let mut counts = vec![0u32; w * h];
    for y in 0..h {
        let (y0, y1) = (y.saturating_sub(r), (y + r + 1).min(h));
        for x in 0..w {
            let (x0, x1) = (x.saturating_sub(r), (x + r + 1).min(w));
            let at = |yy: usize, xx: usize| yy * stride + xx;
            let n = count[at(y1, x1)] + count[at(y0, x0)] - count[at(y0, x1)] - count[at(y1, x0)];
            counts[y * w + x] = n;
            if n > 0 {
                let s = sum[at(y1, x1)] + sum[at(y0, x0)] - sum[at(y0, x1)] - sum[at(y1, x0)];
                out[y * w + x] = (s / n as f64) as f32;
            }
        }
    }
    (out, counts)
}

/// The pixels within `r` (a square neighbourhood) of a `true` pixel of a `[h, w]` mask.
pub fn dilate(mask: &[bool], w: usize, h: usize, r: usize) -> Vec<bool> {
    let ones: Vec<f32> = mask.iter().map(|&m| if m { 1.0 } else { 0.0 }).collect();
    box_mean(&ones, w, h, r)
        .0
        .iter()
        .map(|&v| v > 0.0)
        .collect()
}

/// The median of a non-empty slice (reordered).
fn median(v: &mut [f32]) -> f32 {
    let mid = v.len() / 2;
    *v.select_nth_unstable_by(mid, |a, b| a.total_cmp(b)).1
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::types::Image;
    use rand_distr::{Distribution, StandardNormal};

    #[test]
    fn box_mean_matches_a_direct_sum_and_skips_unknown_values() {
        let (w, h) = (7, 5);
        let mut p: Vec<f32> = (0..w * h).map(|i| ((i * 37) % 11) as f32).collect();
        p[8] = f32::NAN;
        let (got, counts) = box_mean(&p, w, h, 2);
        for y in 0..h {
            for x in 0..w {
                let (mut s, mut n) = (0.0, 0);
                for yy in y.saturating_sub(2)..(y + 3).min(h) {
                    for xx in x.saturating_sub(2)..(x + 3).min(w) {
                        if p[yy * w + xx].is_finite() {
                            s += p[yy * w + xx] as f64;
                            n += 1;
                        }
                    }
                }
                assert!(
                    (got[y * w + x] as f64 - s / n as f64).abs() < 1e-5,
                    "({x}, {y})"
                );
                assert_eq!(counts[y * w + x], n, "({x}, {y})");
            }
        }
        assert!(
            box_mean(&[f32::NAN; 4], 2, 2, 1)
                .0
                .iter()
                .all(|v| v.is_nan())
        );
        let d = dilate(&[false, false, false, true, false, false], 6, 1, 1);
        assert_eq!(d, [false, false, true, true, true, false]);
    }

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
