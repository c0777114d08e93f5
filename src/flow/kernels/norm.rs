//! Instance and group normalisation (the encoders of Note S10) on host values: per image and
//! group of channels, `x̂ = (x − μ)·σ⁻¹` with σ² the variance about the mean plus ε, then
//! `γ_c·x̂ + β_c` per channel — three passes over each group (mean, variance about the mean,
//! normalise with the affine folded in) instead of Burn's chain of whole-tensor operations,
//! groups in parallel; and its gradients in two passes. Instance normalisation is
//! `groups = C`. Statistics accumulate in f64.

use multiversion::multiversion;
use rayon::prelude::*;

/// Independent partial sums of [`sum64`]: separate dependency chains, which the compiler keeps
/// in vector registers (one f64 chain runs at one addition per 4 cycles).
const LANES: usize = 8;

/// `Σ f(v)` over `src` in f64: [`LANES`] interleaved partial sums, then the tail, added in a
/// fixed order (the same result on every thread count).
#[inline(always)] // into the SIMD versions of `normalise_group`
fn sum64(src: &[f32], f: impl Fn(f64) -> f64) -> f64 {
    let mut acc = [0f64; LANES];
    let chunks = src.chunks_exact(LANES);
    let tail = chunks.remainder();
    for c in chunks {
        for (a, &v) in acc.iter_mut().zip(c) {
            *a += f(v as f64);
        }
    }
    acc.iter().sum::<f64>() + tail.iter().map(|&v| f(v as f64)).sum::<f64>()
}

/// Mean and 1/√(var + ε) of one group, accumulated in f64: the mean, then the variance about
/// it.
#[inline(always)]
fn stats(src: &[f32], epsilon: f64) -> (f32, f32) {
    let n = src.len().max(1) as f64;
    let mean = sum64(src, |v| v) / n;
    let var = sum64(src, |v| (v - mean) * (v - mean)) / n;
    (mean as f32, (1.0 / (var + epsilon).sqrt()) as f32)
}

/// One group normalised: `dst = (src − μ)·σ⁻¹·γ_c + β_c` for its channels, `first_channel`
/// on, of `hw` values each.
#[multiversion(targets = "simd")]
fn normalise_group(
    src: &[f32],
    dst: &mut [f32],
    hw: usize,
    first_channel: usize,
    epsilon: f64,
    affine: Option<(&[f32], &[f32])>,
) {
    let (mean, inv) = stats(src, epsilon);
    for (k, (d, s)) in dst.chunks_mut(hw).zip(src.chunks(hw)).enumerate() {
        let (scale, shift) = match affine {
            Some((g, bt)) => (inv * g[first_channel + k], bt[first_channel + k]),
            None => (inv, 0.0),
        };
        for (o, &v) in d.iter_mut().zip(s) {
            *o = (v - mean) * scale + shift;
        }
    }
}

/// The normalisation on host memory, groups in parallel.
///
/// # Shapes
/// `x` `[B, C, HW]` row-major → `[B, C, HW]`; `affine` (γ, β) `[C]` each
pub fn normalise(
    x: &[f32],
    [_, c, hw]: [usize; 3],
    groups: usize,
    epsilon: f64,
    affine: Option<(&[f32], &[f32])>,
) -> Vec<f32> {
    let per_group = (c / groups * hw).max(1);
    let mut out = vec![0f32; x.len()];
    out.par_chunks_mut(per_group)
        .zip(x.par_chunks(per_group))
        .enumerate()
        .for_each(|(i, (dst, src))| {
            let first_channel = (i % groups) * (c / groups);
            normalise_group(src, dst, hw.max(1), first_channel, epsilon, affine);
        });
    out
}

/// Gradients of [`normalise`] with affine parameters: with x̂ = (x − μ)·σ⁻¹ and
/// y = γ_c·x̂ + β_c over a group of N values,
/// `∂L/∂x = σ⁻¹·(g − mean(g) − x̂·mean(g·x̂))` where g = γ_c·∂L/∂y,
/// `∂L/∂γ_c = Σ ∂L/∂y·x̂`, `∂L/∂β_c = Σ ∂L/∂y` (sums over images and pixels).
///
/// # Shapes
/// `x`, `dy` `[B, C, HW]` → (`dx` `[B, C, HW]`, `dγ` `[C]`, `dβ` `[C]`)
pub fn normalise_backward(
    x: &[f32],
    dy: &[f32],
    [_, c, hw]: [usize; 3],
    groups: usize,
    epsilon: f64,
    gamma: &[f32],
) -> (Vec<f32>, Vec<f32>, Vec<f32>) {
    let cg = c / groups;
    let per_group = (cg * hw).max(1);
    let mut dx = vec![0f32; x.len()];
    // Per (image, group): the group's channels' (dγ, dβ) partial sums.
    let partial: Vec<(Vec<f32>, Vec<f32>)> = dx
        .par_chunks_mut(per_group)
        .zip(x.par_chunks(per_group).zip(dy.par_chunks(per_group)))
        .enumerate()
        .map(|(i, (dst, (src, gsrc)))| {
            let (mean, inv) = stats(src, epsilon);
            let first = (i % groups) * cg;
            let (mut dg, mut db) = (vec![0f32; cg], vec![0f32; cg]);
            let (mut s1, mut s2) = (0f64, 0f64);
            for k in 0..cg {
                let (xs, gs) = (&src[k * hw..(k + 1) * hw], &gsrc[k * hw..(k + 1) * hw]);
                let (mut a, mut bsum) = (0f64, 0f64);
                for (&v, &g) in xs.iter().zip(gs) {
                    let xh = (v - mean) * inv;
                    a += (g * xh) as f64;
                    bsum += g as f64;
                }
                dg[k] = a as f32;
                db[k] = bsum as f32;
                let gam = gamma[first + k] as f64;
                s1 += gam * bsum;
                s2 += gam * a;
            }
            let n = (cg * hw).max(1) as f64;
            let (m1, m2) = ((s1 / n) as f32, (s2 / n) as f32);
            for k in 0..cg {
                let gam = gamma[first + k];
                let (xs, gs) = (&src[k * hw..(k + 1) * hw], &gsrc[k * hw..(k + 1) * hw]);
                for ((d, &v), &g) in dst[k * hw..(k + 1) * hw].iter_mut().zip(xs).zip(gs) {
                    let xh = (v - mean) * inv;
                    *d = inv * (gam * g - m1 - xh * m2);
                }
            }
            (dg, db)
        })
        .collect();
    let (mut dgamma, mut dbeta) = (vec![0f32; c], vec![0f32; c]);
    for (i, (dg, db)) in partial.into_iter().enumerate() {
        let first = (i % groups) * cg;
        for k in 0..cg {
            dgamma[first + k] += dg[k];
            dbeta[first + k] += db[k];
        }
    }
    (dx, dgamma, dbeta)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flow::kernels::testing::{Tol, assert_close, cases, values};

    /// A constant map normalises to the shift, not to NaN; a normalised group has mean 0 and
    /// variance 1 (up to ε).
    #[test]
    fn normalised_groups_have_zero_mean_and_unit_variance() {
        let flat = vec![7f32; 16 * 16];
        let y = normalise(&flat, [1, 16, 16], 16, 1e-5, None);
        assert!(y.iter().all(|v| v.is_finite() && v.abs() < 1e-3));
        let mut r = cases("norm stats", 0);
        let x: Vec<f32> = values(&mut r, 2 * 6 * 20, 5.0)
            .iter()
            .map(|v| v + 3.0)
            .collect();
        let y = normalise(&x, [2, 6, 20], 3, 1e-5, None);
        for group in y.chunks_exact(40) {
            let mean = group.iter().sum::<f32>() / 40.0;
            let var = group.iter().map(|v| (v - mean) * (v - mean)).sum::<f32>() / 40.0;
            assert_close(
                &[mean, var],
                &[0.0, 1.0],
                Tol::Abs(1e-4),
                "group statistics",
            );
        }
    }

    /// Property: on random groups (sizes not multiples of the lanes, means far from zero,
    /// instance and group normalisation, with and without γ, β; seeded) the lane sums give the
    /// definition, its mean and variance summed one value at a time in f64, to f32 rounding.
    #[test]
    fn lane_sums_match_the_serial_definition() {
        use rand::RngExt;
        for case in 0..30 {
            let mut r = cases("norm lanes", case);
            let (b, groups, per) = (
                r.random_range(1..=2),
                r.random_range(1..=4),
                r.random_range(1..=3),
            );
            let (c, hw) = (groups * per, r.random_range(1..=300));
            let offset = r.random_range(-50.0f32..50.0);
            let x: Vec<f32> = values(&mut r, b * c * hw, 2.0)
                .iter()
                .map(|v| v + offset)
                .collect();
            let (gamma, beta) = (values(&mut r, c, 1.0), values(&mut r, c, 1.0));
            let affine = (case % 2 == 0).then_some((gamma.as_slice(), beta.as_slice()));
            let mut want = vec![0f32; x.len()];
            for (i, (dst, src)) in want
                .chunks_mut(per * hw)
                .zip(x.chunks(per * hw))
                .enumerate()
            {
                let n = src.len() as f64;
                let mean = src.iter().map(|&v| v as f64).sum::<f64>() / n;
                let var = src
                    .iter()
                    .map(|&v| (v as f64 - mean) * (v as f64 - mean))
                    .sum::<f64>()
                    / n;
                let (mean, inv) = (mean as f32, (1.0 / (var + 1e-5).sqrt()) as f32);
                for (k, (d, s)) in dst.chunks_mut(hw).zip(src.chunks(hw)).enumerate() {
                    let ch = (i % groups) * per + k;
                    let (scale, shift) = match affine {
                        Some((g, bt)) => (inv * g[ch], bt[ch]),
                        None => (inv, 0.0),
                    };
                    for (o, &v) in d.iter_mut().zip(s) {
                        *o = (v - mean) * scale + shift;
                    }
                }
            }
            let got = normalise(&x, [b, c, hw], groups, 1e-5, affine);
            let what = format!("case {case}: {b}×{c}×{hw}, {groups} groups, offset {offset}");
            assert_close(&got, &want, Tol::Scaled(1e-6), &what);
        }
    }

    /// The backward pass equals central differences of ⟨normalise(x), g⟩.
    #[test]
    fn gradients_match_finite_differences() {
        let mut r = cases("norm gradients", 0);
        let shape = [2, 4, 6];
        let n: usize = shape.iter().product();
        let x = values(&mut r, n, 1.0);
        let g = values(&mut r, n, 1.0);
        let gamma = values(&mut r, 4, 1.0);
        let beta = values(&mut r, 4, 1.0);
        let loss = |x: &[f32], gamma: &[f32], beta: &[f32]| -> f64 {
            let y = normalise(x, shape, 2, 1e-5, Some((gamma, beta)));
            y.iter().zip(&g).map(|(a, b)| (a * b) as f64).sum()
        };
        let (dx, dgamma, dbeta) = normalise_backward(&x, &g, shape, 2, 1e-5, &gamma);
        let h = 1e-2f32;
        let numeric = |v: &[f32], f: &dyn Fn(&[f32]) -> f64| -> Vec<f32> {
            (0..v.len())
                .map(|i| {
                    let (mut up, mut down) = (v.to_vec(), v.to_vec());
                    up[i] += h;
                    down[i] -= h;
                    ((f(&up) - f(&down)) / (2.0 * h as f64)) as f32
                })
                .collect()
        };
        let tol = Tol::Scaled(2e-2);
        assert_close(&dx, &numeric(&x, &|v| loss(v, &gamma, &beta)), tol, "∂L/∂x");
        assert_close(
            &dgamma,
            &numeric(&gamma, &|v| loss(&x, v, &beta)),
            tol,
            "∂L/∂γ",
        );
        assert_close(
            &dbeta,
            &numeric(&beta, &|v| loss(&x, &gamma, v)),
            tol,
            "∂L/∂β",
        );
    }
}
