//! The iterative update block (Note S9, Fig. S9a): a motion encoder of the current flow and its
//! correlation features, the ConvGRU of Eqs. S9–S12 with 3×3 convolutions, the flow head that
//! predicts ΔF, and the mask head for convex upsampling.

use burn::nn::conv::Conv2d;
use burn::prelude::*;
use burn::tensor::activation::{relu, sigmoid, tanh};

use super::blocks::conv;
use super::config::MmsConfig;

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
        let c = relu(self.corr2.forward(relu(self.corr1.forward(corr))));
        let f = relu(self.flow2.forward(relu(self.flow1.forward(flow.clone()))));
        let m = relu(self.out.forward(Tensor::cat(vec![c, f], 1)));
        Tensor::cat(vec![m, flow], 1)
    }
}

/// ConvGRU, Eqs. S9–S12: z = σ(Conv[h, x]), r = σ(Conv[h, x]), h̃ = tanh(Conv[r⊙h, x]),
/// h' = (1 − z)⊙h + z⊙h̃.
#[derive(Module, Debug)]
pub struct ConvGru {
    convz: Conv2d,
    convr: Conv2d,
    convq: Conv2d,
}

impl ConvGru {
    pub fn new(hidden: usize, input: usize, device: &Device) -> Self {
        Self {
            convz: conv(hidden + input, hidden, 3, 1, 1, device),
            convr: conv(hidden + input, hidden, 3, 1, 1, device),
            convq: conv(hidden + input, hidden, 3, 1, 1, device),
        }
    }

    /// # Shapes
    /// `h`: `[B, Ch, H, W]`, `x`: `[B, Cx, H, W]` → `[B, Ch, H, W]`
    pub fn forward(&self, h: Tensor<4>, x: Tensor<4>) -> Tensor<4> {
        let hx = Tensor::cat(vec![h.clone(), x.clone()], 1);
        let z = sigmoid(self.convz.forward(hx.clone())); // Eq. S9
        let r = sigmoid(self.convr.forward(hx)); // Eq. S10
        let q = tanh(self.convq.forward(Tensor::cat(vec![r * h.clone(), x], 1))); // Eq. S11
        (z.clone().neg() + 1.0) * h + z * q // Eq. S12
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
        let delta = self.flow2.forward(relu(self.flow1.forward(hidden.clone())));
        // RAFT scales the mask logits by 1/4 to balance their gradients against the flow's.
        let mask = with_mask.then(|| {
            self.mask2
                .forward(relu(self.mask1.forward(hidden.clone())))
                .mul_scalar(0.25)
        });
        (hidden, delta, mask)
    }
}
