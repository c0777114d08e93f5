//! The iterative update block (Note S9, Fig. S9a): a motion encoder of the current flow and its
//! correlation features, the ConvGRU of Eqs. S9–S12 ([`super::gru`]), the flow head that
//! predicts ΔF, and the mask head for convex upsampling.

use burn::nn::conv::Conv2d;
use burn::prelude::*;

use super::blocks::conv;
use super::config::MmsConfig;
use super::gru::ConvGru;
use crate::flow::ops::{Act, conv_layer, conv_stacked};

/// Encodes (correlation, flow) into motion features, keeping the flow itself as two channels.
#[derive(Module, Debug)]
pub struct MotionEncoder {
    corr1: Conv2d,
    corr2: Conv2d,
    flow1: Conv2d,
    flow2: Conv2d,
    out: Conv2d,
}

impl MotionEncoder {
    pub fn new(cfg: &MmsConfig, device: &Device) -> Self {
        let [dc, df, dout] = cfg.motion_dims;
        Self {
            corr1: conv(cfg.corr_channels(), dc, 1, 1, 1, device),
            corr2: conv(dc, dc, 3, 1, 1, device),
            flow1: conv(2, df, 7, 1, 1, device),
            flow2: conv(df, df / 2, 3, 1, 1, device),
            out: conv(dc + df / 2, dout - 2, 3, 1, 1, device),
        }
    }

    /// # Shapes
    /// `corr`: `[B, L·k², H, W]`, `flow`: `[B, 2, H, W]` → `[B, motion_dims[2], H, W]`
    pub fn forward(&self, corr: Tensor<4>, flow: Tensor<4>) -> Tensor<4> {
        let relu = Act::Relu;
        let c = conv_layer(&self.corr2, conv_layer(&self.corr1, corr, relu), relu);
        let f = conv_layer(
            &self.flow2,
            conv_layer(&self.flow1, flow.clone(), relu),
            relu,
        );
        let m = conv_layer(&self.out, Tensor::cat(vec![c, f], 1), relu);
        Tensor::cat(vec![m, flow], 1)
    }
}

/// The update block: motion encoder → GRU → flow head (ΔF) and mask head.
#[derive(Module, Debug)]
pub struct UpdateBlock {
    motion: MotionEncoder,
    gru: ConvGru,
    flow1: Conv2d,
    flow2: Conv2d,
    mask1: Conv2d,
    mask2: Conv2d,
}

impl UpdateBlock {
    pub fn new(cfg: &MmsConfig, device: &Device) -> Self {
        let input = cfg.motion_dims[2] + cfg.context_dim;
        Self {
            motion: MotionEncoder::new(cfg, device),
            gru: ConvGru::new(cfg.hidden_dim, input, device),
            flow1: conv(cfg.hidden_dim, cfg.head_dim, 3, 1, 1, device),
            flow2: conv(cfg.head_dim, 2, 3, 1, 1, device),
            mask1: conv(cfg.hidden_dim, cfg.head_dim, 3, 1, 1, device),
            mask2: conv(cfg.head_dim, 64 * 9, 1, 1, 1, device),
        }
    }

    /// One refinement step. Returns the new hidden state, ΔF, and (when `with_mask`) the
    /// upsampling mask logits.
    ///
    /// # Shapes
    /// `hidden` `[B, Ch, H, W]`, `context` `[B, Cc, H, W]`, `corr` `[B, L·k², H, W]`,
    /// `flow` `[B, 2, H, W]` → (`[B, Ch, H, W]`, `[B, 2, H, W]`, `[B, 576, H, W]`)
    pub fn forward(
        &self,
        hidden: Tensor<4>,
        context: Tensor<4>,
        corr: Tensor<4>,
        flow: Tensor<4>,
        with_mask: bool,
    ) -> (Tensor<4>, Tensor<4>, Option<Tensor<4>>) {
        let motion = self.motion.forward(corr, flow);
        let hidden = self
            .gru
            .forward(hidden, Tensor::cat(vec![context, motion], 1));
        if !with_mask {
            let head = conv_layer(&self.flow1, hidden.clone(), Act::Relu);
            let delta = conv_layer(&self.flow2, head, Act::Identity);
            return (hidden, delta, None);
        }
        // Both heads open with a 3×3 convolution of the hidden state: one convolution with the
        // two kernels stacked.
        let [flow_head, mask_head] =
            conv_stacked([&self.flow1, &self.mask1], hidden.clone(), Act::Relu); // 2 × [B, head, H, W]
        let delta = conv_layer(&self.flow2, flow_head, Act::Identity);
        // RAFT scales the mask logits by 1/4 to balance their gradients against the flow's.
        let mask = conv_layer(&self.mask2, mask_head, Act::Identity).mul_scalar(0.25);
        (hidden, delta, Some(mask))
    }

    /// The upsampling mask of a hidden state on its own (for a caller that learns only after
    /// an update that it was the last).
    ///
    /// # Shapes
    /// `[B, Ch, H, W]` → `[B, 64·9, H, W]`
    pub fn mask(&self, hidden: Tensor<4>) -> Tensor<4> {
        let head = conv_layer(&self.mask1, hidden, Act::Relu);
        conv_layer(&self.mask2, head, Act::Identity).mul_scalar(0.25)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flow::kernels::testing::{Tol, cases};
    use crate::flow::ops::testing::{assert_tensors_close, random};
    use burn::tensor::activation::relu;

    /// The stacked-kernel heads give what the two heads give one by one.
    #[test]
    fn stacked_heads_match_separate_heads() {
        let dev = Device::flex();
        let cfg = MmsConfig::mms_small();
        let block = UpdateBlock::new(&cfg, &dev);
        let hidden = random(&mut cases("heads", 0), [1, cfg.hidden_dim, 5, 6], 1.0, &dev);
        let context = Tensor::<4>::zeros([1, cfg.context_dim, 5, 6], &dev);
        let corr = Tensor::<4>::zeros([1, cfg.corr_channels(), 5, 6], &dev);
        let flow = Tensor::<4>::zeros([1, 2, 5, 6], &dev);
        // Run the heads on the hidden state the block itself produces.
        let (h2, d2, m2) = block.forward(hidden, context, corr, flow, true);
        let d_ref = block.flow2.forward(relu(block.flow1.forward(h2.clone())));
        let m_ref = block
            .mask2
            .forward(relu(block.mask1.forward(h2)))
            .mul_scalar(0.25);
        assert_tensors_close(d2, d_ref, Tol::Abs(1e-5), "delta");
        let m2 = m2.expect("mask requested");
        assert_tensors_close(m2, m_ref, Tol::Abs(1e-5), "mask");
    }
}
