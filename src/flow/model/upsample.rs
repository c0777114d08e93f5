//! Convex upsampling (Note S9): every full-resolution flow vector is a softmax-weighted convex
//! combination of the 3×3 coarse neighbours of its 1/8-resolution cell (their flow × 8, in
//! full-resolution pixels), with the 8×8×9 weights predicted by the mask head:
//! `F↑(8y + i, 8x + j) = Σ_k softmax_k(m[k, i, j](y, x)) · 8 F(y + ky − 1, x + kx − 1)`.
//! The operation is [`ops::convex_upsample`].

use burn::prelude::*;

use crate::flow::ops;

/// # Shapes
/// `flow` `[B, 2, H, W]` (1/8-resolution pixels), `mask` `[B, 576, H, W]` → `[B, 2, 8H, 8W]`
/// (full-resolution pixels). The softmax subtracts the maximum, so huge logits stay finite.
pub fn convex_upsample(flow: Tensor<4>, mask: Tensor<4>) -> Tensor<4> {
    ops::convex_upsample(flow, mask)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flow::kernels::testing::{Tol, assert_close};

    #[test]
    fn constant_flow_upsamples_to_eight_times_itself() {
        let dev = Device::flex();
        let flow = Tensor::<4>::ones([1, 2, 3, 4], &dev)
            * Tensor::<1>::from_floats([1.5, -0.5], &dev).reshape([1, 2, 1, 1]);
        let mask = Tensor::<4>::random(
            [1, 576, 3, 4],
            burn::tensor::Distribution::Normal(0.0, 3.0),
            &dev,
        );
        let up = convex_upsample(flow, mask);
        assert_eq!(up.dims(), [1, 2, 24, 32]);
        // Interior cells only: at the border the zero padding of unfold enters the combination.
        let v: Vec<f32> = up
            .slice([0..1, 0..2, 8..16, 8..24])
            .into_data()
            .try_to_vec::<f32>()
            .unwrap();
        let want: Vec<f32> = [12.0f32, -4.0]
            .iter()
            .flat_map(|&c| std::iter::repeat_n(c, v.len() / 2))
            .collect();
        assert_close(&v, &want, Tol::Abs(1e-4), "interior of 8 × (1.5, −0.5)");
    }

    #[test]
    fn huge_mask_logits_stay_finite() {
        let dev = Device::flex();
        let flow = Tensor::<4>::ones([1, 2, 2, 2], &dev);
        let mask = Tensor::<4>::ones([1, 576, 2, 2], &dev).mul_scalar(1e30);
        let v: Vec<f32> = convex_upsample(flow, mask)
            .into_data()
            .try_to_vec::<f32>()
            .unwrap();
        assert!(v.iter().all(|x| x.is_finite()));
    }
}
