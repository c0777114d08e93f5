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
        let b = image1.dims()[0];
        // Both frames through the shared feature encoder in one batch; the context encoder
        // beside it (concurrently at inference).
        let (features, context) = ops::both(
            &image1,
            || self.features(Tensor::cat(vec![image1.clone(), image2.clone()], 0)),
            || self.context(image1.clone()),
        );
        let f1 = features.clone().narrow(0, 0, b); // [B, C, H/8, W/8]
        let f2 = features.narrow(0, b, b);
        self.iterate(f1, f2, context, iters, all, flow_init, None)
            .predictions
    }

    /// The feature encoding of images in [0, 1]: what the correlation compares, computed once
    /// per frame (a video reuses frame n's as the first of pair (n, n + 1)).
    ///
    /// # Shapes
    /// `[B, 3, H, W]` → `[B, C, H/8, W/8]`
    pub fn features(&self, images: Tensor<4>) -> Tensor<4> {
        self.feature_encoder.forward(normalise(images))
    }

    /// The context encoding of the first frame, before its split into hidden state and context.
    ///
    /// # Shapes
    /// `[B, 3, H, W]` → `[B, Ch + Cc, H/8, W/8]`
    pub fn context(&self, image1: Tensor<4>) -> Tensor<4> {
        self.context_encoder.forward(normalise(image1))
    }

    /// The refinements from encoded frames: the correlation pyramid of `f1` and `f2`, then up to
    /// `iters` ConvGRU updates from `flow_init` (zero when `None`), each upsampled when `all`
    /// (the last only otherwise). With `stop`, the updates end early once the mean length of an
    /// update falls below `stop` full-resolution pixels.
    ///
    /// # Shapes
    /// `f1`, `f2`: `[B, C, H/8, W/8]`; `context`: `[B, Ch + Cc, H/8, W/8]`; `flow_init`:
    /// `[B, 2, H/8, W/8]` → predictions `[B, 2, H, W]`, `flow8` `[B, 2, H/8, W/8]`
    #[allow(clippy::too_many_arguments)]
    pub fn iterate(
        &self,
        f1: Tensor<4>,
        f2: Tensor<4>,
        context: Tensor<4>,
        iters: usize,
        all: bool,
        flow_init: Option<Tensor<4>>,
        stop: Option<f32>,
    ) -> Iterations {
        let [b, _, h8, w8] = f1.dims();
        let device = f1.device();
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
        let mut done = 0;
        for i in 0..iters {
            // RAFT detaches the lookup position: gradients flow through ΔF, not through where
            // the correlation was sampled.
            coords1 = coords1.detach();
            let window = corr.lookup(coords1.clone());
            let flow = coords1.clone() - coords0.clone();
            let last = i + 1 == iters;
            let with_mask = all || (last && stop.is_none());
            let (h_new, delta, mask) =
                self.update
                    .forward(hidden, context.clone(), window, flow, with_mask);
            hidden = h_new;
            // The update's mean length in full-resolution pixels (8 per cell).
            let settled = stop.is_some_and(|px| {
                let len = (delta.clone() * delta.clone()).sum_dim(1).sqrt().mean();
                len.into_scalar::<f32>() * 8.0 < px
            });
            coords1 = coords1 + delta;
            done = i + 1;
            if let Some(mask) = mask {
                predictions.push(convex_upsample(coords1.clone() - coords0.clone(), mask));
            }
            if stop.is_some() && !all && (last || settled) {
                let mask = self.update.mask(hidden.clone());
                predictions.push(convex_upsample(coords1.clone() - coords0.clone(), mask));
                break;
            }
        }
        Iterations {
            predictions,
            flow8: coords1 - coords0,
            iters: done,
        }
    }
}

/// What [`Mms::iterate`] returns.
pub struct Iterations {
    /// The upsampled flow after each update (`all`) or after the last.
    ///
    /// # Shapes
    /// each `[B, 2, H, W]`, pixels
    pub predictions: Vec<Tensor<4>>,
    /// The last flow on the network's grid, in 1/8-resolution pixels: a video's warm start.
    ///
    /// # Shapes
    /// `[B, 2, H/8, W/8]`
    pub flow8: Tensor<4>,
    /// The updates run (fewer than asked when `stop` ended them).
    pub iters: usize,
}

/// [0, 1] → [−1, 1], as RAFT normalises its inputs.
fn normalise(x: Tensor<4>) -> Tensor<4> {
    x.mul_scalar(2.0).sub_scalar(1.0)
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
