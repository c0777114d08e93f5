//! Instance and group normalisation for inference on the CPU (the encoders of Note S10): the
//! numbers of `burn::nn::{InstanceNorm, GroupNorm}`, in three passes over each group (mean,
//! variance about the mean, normalise with the affine folded in) instead of burn's chain of
//! whole-tensor operations, groups in parallel.
//!
//! The non-autodiff CPU device takes [`group_norm`]; training reaches [`normalise`] and
//! [`normalise_backward`] through the differentiable operation of [`super::train_norm`].

use burn::prelude::*;
use rayon::prelude::*;

/// Whether `x` can take the host path.
pub fn on_host(x: &Tensor<4>) -> bool {
    !x.is_autodiff() && x.device() == Device::flex()
}

/// Group normalisation of `x` over `groups` channel groups: per image and group,
/// `(x − mean) / √(var + ε)`, then `γ_c·x + β_c` per channel when the affine parameters are
/// given. Instance normalisation is `groups = C`. `None` when the data is not f32 (the caller
/// then uses burn's layer).
///
/// # Shapes
/// `[B, C, H, W]` → `[B, C, H, W]`; `gamma`, `beta`: `[C]`
pub fn group_norm(
    x: Tensor<4>,
    groups: usize,
    epsilon: f64,
    gamma: Option<Tensor<1>>,
    beta: Option<Tensor<1>>,
) -> Option<Tensor<4>> {
    let [b, c, h, w] = x.dims();
    if groups == 0 || c % groups != 0 {
        return None;
    }
    let device = x.device();
    let data = x.into_data();
    let xv = data.as_slice::<f32>().ok()?;
    let affine = match (gamma, beta) {
        (Some(g), Some(bt)) => Some((
            g.into_data().try_into_vec::<f32>().ok()?,
            bt.into_data().try_into_vec::<f32>().ok()?,
        )),
        _ => None,
    };
    let affine = affine.as_ref().map(|(g, bt)| (g.as_slice(), bt.as_slice()));
    let out = normalise(xv, [b, c, h * w], groups, epsilon, affine);
    Some(Tensor::from_data(
        TensorData::new(out, [b, c, h, w]),
        &device,
    ))
}

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
    use burn::nn::{GroupNormConfig, InstanceNormConfig};
    use burn::tensor::Distribution;

    /// Instance and group normalisation match burn's layers, with trained-looking affine
    /// parameters, on an offset, badly scaled input.
    #[test]
    fn host_norms_match_burn() {
        let dev = Device::flex();
        let x = Tensor::<4>::random([2, 16, 7, 9], Distribution::Normal(3.0, 5.0), &dev);
        let mut inst = InstanceNormConfig::new(16).init(&dev);
        let mut group = GroupNormConfig::new(8, 16).init(&dev);
        let g = Tensor::<1>::random([16], Distribution::Normal(1.0, 0.5), &dev);
        let bt = Tensor::<1>::random([16], Distribution::Normal(0.0, 0.5), &dev);
        inst.gamma = Some(burn::module::Param::from_tensor(g.clone()));
        inst.beta = Some(burn::module::Param::from_tensor(bt.clone()));
        group.gamma = Some(burn::module::Param::from_tensor(g.clone()));
        group.beta = Some(burn::module::Param::from_tensor(bt.clone()));
        let got = group_norm(
            x.clone(),
            16,
            inst.epsilon,
            Some(g.clone()),
            Some(bt.clone()),
        )
        .expect("f32");
        let diff: f32 = (got - inst.forward(x.clone())).abs().max().into_scalar();
        assert!(diff < 1e-4, "instance: max difference {diff}");
        let got = group_norm(x.clone(), 8, group.epsilon, Some(g), Some(bt)).expect("f32");
        let diff: f32 = (got - group.forward(x.clone())).abs().max().into_scalar();
        assert!(diff < 1e-4, "group: max difference {diff}");
        // A constant map normalises to the shift, not to NaN.
        let flat = Tensor::<4>::ones([1, 16, 4, 4], &dev).mul_scalar(7.0);
        let y = group_norm(flat, 16, 1e-5, None, None).expect("f32");
        let m: f32 = y.abs().max().into_scalar();
        assert!(m.is_finite() && m < 1e-3, "constant map gave {m}");
    }
}
