//! The sequence-wise exponentially weighted L1 loss (Note S11, Eq. S16).
//!
//! Eq. S16 writes the weight of prediction i (of N) as ρ^(i−N); with ρ = 0.8 < 1 that would
//! weight the *earliest* predictions most, contradicting the text ("greater importance to later
//! iterations"). We use ρ^(N−i), RAFT's weighting, which matches the text: the last prediction
//! has weight 1, the one before 0.8, and so on.

use burn::prelude::*;

/// Ground-truth vectors at least this long are treated as invalid, as RAFT does.
pub const MAX_FLOW: f32 = 400.0;

/// # Shapes
/// `predictions`: N × `[B, 2, H, W]`, `gt`: `[B, 2, H, W]`, `valid`: `[B, 1, H, W]` (1 or 0)
/// → scalar `[1]`: Σ_i ρ^(N−i) · mean(valid · |f_i − f_gt|).
pub fn sequence_loss(
    predictions: &[Tensor<4>],
    gt: Tensor<4>,
    valid: Tensor<4>,
    rho: f32,
) -> Tensor<1> {
    let n = predictions.len();
    let mag = gt.clone().powi_scalar(2).sum_dim(1).sqrt(); // [B, 1, H, W]
    let valid = valid * mag.lower_elem(MAX_FLOW).float();
    let mut total: Option<Tensor<1>> = None;
    for (i, pred) in predictions.iter().enumerate() {
        let weight = rho.powi((n - 1 - i) as i32);
        let term = ((pred.clone() - gt.clone()).abs() * valid.clone())
            .mean()
            .mul_scalar(weight);
        total = Some(match total {
            Some(t) => t + term,
            None => term,
        });
    }
    total.unwrap_or_else(|| Tensor::zeros([1], &gt.device()))
}

/// The per-pixel weights of the loss: `valid`, times `moving_weight` where the true motion is
/// over 0.5 px (`TrainConfig::moving_weight`; 1 leaves `valid` as it is).
///
/// # Shapes
/// `gt`: `[B, 2, H, W]`, `valid`: `[B, 1, H, W]` → `[B, 1, H, W]`
pub fn moving_weights(gt: Tensor<4>, valid: Tensor<4>, moving_weight: f32) -> Tensor<4> {
    if moving_weight == 1.0 {
        return valid;
    }
    let moving = gt.powi_scalar(2).sum_dim(1).greater_elem(0.25).float(); // |f| > 0.5
    valid * (moving.mul_scalar(moving_weight - 1.0).add_scalar(1.0))
}

/// Mean end-point error of `pred` over valid pixels, for progress reports.
///
/// # Shapes
/// `[B, 2, H, W]`, `[B, 2, H, W]`, `[B, 1, H, W]` → scalar
pub fn mean_epe(pred: Tensor<4>, gt: Tensor<4>, valid: Tensor<4>) -> f32 {
    let epe = (pred - gt).powi_scalar(2).sum_dim(1).sqrt(); // [B, 1, H, W]
    let num: f32 = (epe * valid.clone()).sum().into_scalar();
    let den: f32 = valid.sum().into_scalar();
    num / den.max(1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn later_predictions_weigh_more() {
        let dev = Device::flex();
        let gt = Tensor::<4>::zeros([1, 2, 4, 4], &dev);
        let valid = Tensor::<4>::ones([1, 1, 4, 4], &dev);
        let good = Tensor::<4>::zeros([1, 2, 4, 4], &dev);
        let bad = Tensor::<4>::ones([1, 2, 4, 4], &dev);
        let early_bad: f32 =
            sequence_loss(&[bad.clone(), good.clone()], gt.clone(), valid.clone(), 0.8)
                .into_scalar();
        let late_bad: f32 =
            sequence_loss(&[good, bad], gt.clone(), valid.clone(), 0.8).into_scalar();
        assert!((early_bad - 0.8).abs() < 1e-6 && (late_bad - 1.0).abs() < 1e-6);
        // Absurd ground truth is ignored.
        let huge = Tensor::<4>::ones([1, 2, 4, 4], &dev).mul_scalar(1e4);
        let l: f32 =
            sequence_loss(&[Tensor::zeros([1, 2, 4, 4], &dev)], huge, valid, 0.8).into_scalar();
        assert_eq!(l, 0.0);
    }

    /// With a moving weight w, an error on a moving pixel costs w times one on a still pixel.
    #[test]
    fn moving_pixels_weigh_moving_weight_times_more() {
        let dev = Device::flex();
        // Pixel 0 moves 2 px; pixels 1..3 stand still; the prediction is off by 1 px in u on
        // pixel 0 in one case and on pixel 1 in the other.
        let gt = Tensor::<4>::from_floats([[[[2.0, 0.0, 0.0, 0.0]], [[0.0; 4]]]], &dev);
        let valid = Tensor::<4>::ones([1, 1, 1, 4], &dev);
        let off_moving = Tensor::<4>::from_floats([[[[3.0, 0.0, 0.0, 0.0]], [[0.0; 4]]]], &dev);
        let off_still = Tensor::<4>::from_floats([[[[2.0, 1.0, 0.0, 0.0]], [[0.0; 4]]]], &dev);
        let w = moving_weights(gt.clone(), valid.clone(), 10.0);
        let a: f32 = sequence_loss(
            std::slice::from_ref(&off_moving),
            gt.clone(),
            w.clone(),
            0.8,
        )
        .into_scalar();
        let b: f32 =
            sequence_loss(std::slice::from_ref(&off_still), gt.clone(), w, 0.8).into_scalar();
        assert!((a / b - 10.0).abs() < 1e-5, "{a} / {b}");
        // Weight 1 is the plain loss.
        let plain = moving_weights(gt.clone(), valid.clone(), 1.0);
        let c: f32 = sequence_loss(&[off_moving], gt.clone(), plain, 0.8).into_scalar();
        let d: f32 = sequence_loss(&[off_still], gt, valid, 0.8).into_scalar();
        assert!((c - d).abs() < 1e-7);
    }
}
