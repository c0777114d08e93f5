//! Instance and group normalisation (the encoders of Note S10) on host values: per image and
//! group of channels, `x̂ = (x − μ)·σ⁻¹` with σ² the variance about the mean plus ε, then
//! `γ_c·x̂ + β_c` per channel — three passes over each group (mean, variance about the mean,
//! normalise with the affine folded in) instead of Burn's chain of whole-tensor operations,
//! groups in parallel; and its gradients in two passes. Instance normalisation is
//! `groups = C`. Statistics accumulate in f64.

use rayon::prelude::*;

/// Mean and 1/√(var + ε) of one group, accumulated in f64.
fn stats(src: &[f32], epsilon: f64) -> (f32, f32) {
    let n = src.len().max(1) as f64;
    let mean = src.iter().map(|&v| v as f64).sum::<f64>() / n;
    let var = src
        .iter()
        .map(|&v| {
            let d = v as f64 - mean;
            d * d
        })
        .sum::<f64>()
        / n;
    (mean as f32, (1.0 / (var + epsilon).sqrt()) as f32)
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
            let (mean, inv) = stats(src, epsilon);
            let first_channel = (i % groups) * (c / groups);
            for (k, (d, s)) in dst
                .chunks_mut(hw.max(1))
                .zip(src.chunks(hw.max(1)))
                .enumerate()
            {
                let (scale, shift) = match affine {
                    Some((g, bt)) => (inv * g[first_channel + k], bt[first_channel + k]),
                    None => (inv, 0.0),
                };
                for (o, &v) in d.iter_mut().zip(s) {
                    *o = (v - mean) * scale + shift;
                }
            }
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
