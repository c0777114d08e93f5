//! Instance and group normalisation for inference on the CPU (the encoders of Note S10): the
//! numbers of `burn::nn::{InstanceNorm, GroupNorm}`, in three passes over each group (mean,
//! variance about the mean, normalise with the affine folded in) instead of burn's chain of
//! whole-tensor operations, groups in parallel.
//!
//! Only the non-autodiff CPU device takes this path; training keeps burn's layers.

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
    let per_group = c / groups * h * w;
    let hw = h * w;
    let mut out = vec![0f32; xv.len()];
    out.par_chunks_mut(per_group.max(1))
        .zip(xv.par_chunks(per_group.max(1)))
        .enumerate()
        .for_each(|(i, (dst, src))| {
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
            let inv = (1.0 / (var + epsilon).sqrt()) as f32;
            let mean = mean as f32;
            let first_channel = (i % groups) * (c / groups);
            for (k, (d, s)) in dst
                .chunks_mut(hw.max(1))
                .zip(src.chunks(hw.max(1)))
                .enumerate()
            {
                let (scale, shift) = match &affine {
                    Some((g, bt)) => (inv * g[first_channel + k], bt[first_channel + k]),
                    None => (inv, 0.0),
                };
                for (o, &v) in d.iter_mut().zip(s) {
                    *o = (v - mean) * scale + shift;
                }
            }
        });
    Some(Tensor::from_data(TensorData::new(out, [b, c, h, w]), &device))
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
        let got = group_norm(x.clone(), 16, inst.epsilon, Some(g.clone()), Some(bt.clone()))
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
