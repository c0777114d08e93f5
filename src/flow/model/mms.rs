//! The Meta-Motion Sense network (Notes S9–S11): DSMSCE feature and context encoders, the
//! correlation pyramid, `iters` ConvGRU refinements from zero flow, convex 8× upsampling.

use burn::prelude::*;
use burn::tensor::activation::{relu, tanh};

use super::config::MmsConfig;
use super::corr::CorrPyramid;
use super::encoder::Dsmsce;
use super::update::UpdateBlock;
use super::upsample::convex_upsample;
use crate::flow::ops;

/// The network. Inputs are images in [0, 1] whose sides are multiples of 8 (see
/// [`super::padder::InputPadder`] for other sizes).
#[derive(Module, Debug)]
pub struct Mms {
    feature_encoder: Dsmsce,
    context_encoder: Dsmsce,
    update: UpdateBlock,
    hidden_dim: usize,
    corr_levels: usize,
    corr_radius: usize,
}

impl Mms {
    /// A freshly initialised network on `device`.
    pub fn new(cfg: &MmsConfig, device: &Device) -> Self {
        Self {
            feature_encoder: Dsmsce::new(
                cfg.encoder_dims,
                cfg.feature_dim,
                &cfg.dilations,
                cfg.feature_norm,
                device,
            ),
            context_encoder: Dsmsce::new(
                cfg.encoder_dims,
                cfg.hidden_dim + cfg.context_dim,
                &cfg.dilations,
                cfg.context_norm,
                device,
            ),
            update: UpdateBlock::new(cfg, device),
            hidden_dim: cfg.hidden_dim,
            corr_levels: cfg.corr_levels,
            corr_radius: cfg.corr_radius,
        }
    }

    /// Flow predictions after each of `iters` refinements (all of them when `all`, for the
    /// sequence loss; only the last otherwise), at full resolution in pixels.
    ///
    /// # Shapes
    /// `image1`, `image2`: `[B, 3, H, W]` in [0, 1], H and W multiples of 8 →
    /// `iters` (or 1) × `[B, 2, H, W]`
    pub fn forward(
        &self,
        image1: Tensor<4>,
        image2: Tensor<4>,
        iters: usize,
        all: bool,
    ) -> Vec<Tensor<4>> {
        self.forward_from(image1, image2, iters, all, None)
    }

    /// [`Mms::forward`] starting from `flow_init` (`[B, 2, H/8, W/8]`, in 1/8-resolution
    /// pixels) instead of zero flow: RAFT's warm start.
    pub fn forward_from(
        &self,
        image1: Tensor<4>,
        image2: Tensor<4>,
        iters: usize,
        all: bool,
        flow_init: Option<Tensor<4>>,
    ) -> Vec<Tensor<4>> {
        let [b, _, h, w] = image1.dims();
        let (h8, w8) = (h / 8, w / 8);
        let device = image1.device();
        // [0, 1] → [−1, 1], as RAFT normalises its inputs.
        let norm = |x: Tensor<4>| x.mul_scalar(2.0).sub_scalar(1.0);
        // Both frames through the shared feature encoder in one batch; the context encoder
        // beside it (concurrently at inference).
        let features = || {
            self.feature_encoder.forward(Tensor::cat(
                vec![norm(image1.clone()), norm(image2.clone())],
                0,
            ))
        };
        let context = || self.context_encoder.forward(norm(image1.clone())); // [B, Ch + Cc, H/8, W/8]
        let (features, context) = ops::both(&image1, features, context);
        let f1 = features.clone().narrow(0, 0, b); // [B, C, H/8, W/8]
        let f2 = features.narrow(0, b, b);
        let corr = CorrPyramid::new(f1, f2, self.corr_levels, self.corr_radius);
        let ctx_dim = context.dims()[1] - self.hidden_dim;
        let mut hidden = tanh(context.clone().narrow(1, 0, self.hidden_dim));
        let context = relu(context.narrow(1, self.hidden_dim, ctx_dim));

        let coords0 = coordinate_grid(b, h8, w8, &device); // [B, 2, H/8, W/8] = (x, y)
        let mut coords1 = match flow_init {
            Some(init) => coords0.clone() + init,
            None => coords0.clone(),
        };
        let mut predictions = Vec::with_capacity(if all { iters } else { 1 });
        for i in 0..iters {
            // RAFT detaches the lookup position: gradients flow through ΔF, not through where
            // the correlation was sampled.
            coords1 = coords1.detach();
            let window = corr.lookup(coords1.clone());
            let flow = coords1.clone() - coords0.clone();
            let last = i + 1 == iters;
            let (h_new, delta, mask) =
                self.update
                    .forward(hidden, context.clone(), window, flow, all || last);
            hidden = h_new;
            coords1 = coords1 + delta;
            if let Some(mask) = mask {
                predictions.push(convex_upsample(coords1.clone() - coords0.clone(), mask));
            }
        }
        predictions
    }
}

/// Pixel coordinates `(x, y)` of every cell.
///
/// # Shapes
/// → `[B, 2, H, W]`
pub fn coordinate_grid(b: usize, h: usize, w: usize, device: &Device) -> Tensor<4> {
    let xs = Tensor::<1, Int>::arange(0..w as i64, device)
        .float()
        .reshape([1, 1, 1, w])
        .expand([b, 1, h, w]);
    let ys = Tensor::<1, Int>::arange(0..h as i64, device)
        .float()
        .reshape([1, 1, h, 1])
        .expand([b, 1, h, w]);
    Tensor::cat(vec![xs, ys], 1)
}
