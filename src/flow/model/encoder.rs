//! The Dual-Stage Multi-Scale Composite Encoder (DSMSCE, Note S10): a convolutional stem and
//! residual stages down to 1/8 resolution, then a pyramid-pooling block (Eq. S13) and a
//! dilated atrous spatial pyramid pooling block (DASPP, Eqs. S14–S15).

use burn::nn::conv::Conv2d;
use burn::prelude::*;
use burn::tensor::activation::relu;
use burn::tensor::module::adaptive_avg_pool2d;

use super::blocks::{Norm, ResidualBlock, conv};
use super::config::NormKind;
use crate::flow::ops::{Act, conv_layer};

/// Bilinear resize to `[h, w]` with PyTorch's `align_corners = false`, written as two matrix
/// products, `Ry · X · Rxᵀ`: the same values as Burn's `interpolate` (tested below), but with a
/// backward pass on every backend (cubecl's bilinear `interpolate` has none, so the GPU backends
/// could not train through the pyramid pooling).
///
/// # Shapes
/// `[B, C, m, n]` → `[B, C, h, w]`
pub fn resize(x: Tensor<4>, h: usize, w: usize) -> Tensor<4> {
    let [_, _, m, n] = x.dims();
    let device = x.device();
    let ry = Tensor::<2>::from_data(TensorData::new(resize_weights(m, h), [h, m]), &device);
    let rxt =
        Tensor::<2>::from_data(TensorData::new(resize_weights(n, w), [w, n]), &device).transpose();
    let ry = ry.unsqueeze::<4>(); // [1, 1, h, m]
    let rxt = rxt.unsqueeze::<4>(); // [1, 1, n, w]
    ry.matmul(x).matmul(rxt) // [B, C, h, m] → [B, C, h, w]
}

/// The `[out, len]` row-major matrix of 1-D linear interpolation from `len` samples to `out`
/// with `align_corners = false`: output `i` reads source position `(i + ½)·len/out − ½`,
/// clamped at 0, between its two neighbours (the last sample repeats past the end).
fn resize_weights(len: usize, out: usize) -> Vec<f32> {
    let mut r = vec![0.0f32; out * len];
    let scale = len as f64 / out as f64;
    for i in 0..out {
        let src = ((i as f64 + 0.5) * scale - 0.5).max(0.0);
        let i0 = (src.floor() as usize).min(len - 1);
        let i1 = (i0 + 1).min(len - 1);
        let t = (src - i0 as f64) as f32;
        r[i * len + i0] += 1.0 - t;
        r[i * len + i1] += t;
    }
    r
}

/// Pyramid pooling (Eq. S13): P0 = X, P_m = Upsample(AvgPool(X; m×m)) for m = 1, 2, 3,
/// concatenated to 4C channels and fused back to C by a 3×3 convolution.
#[derive(Module, Debug)]
pub struct PyramidPooling {
    fuse: Conv2d,
    norm: Norm,
}

impl PyramidPooling {
    pub fn new(channels: usize, norm: NormKind, device: &Device) -> Self {
        Self {
            fuse: conv(4 * channels, channels, 3, 1, 1, device),
            norm: Norm::new(norm, channels, device),
        }
    }

    /// # Shapes
    /// `[B, C, H, W]` → `[B, C, H, W]`
    pub fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let [_, _, h, w] = x.dims();
        let mut branches = vec![x.clone()];
        for m in 1..=3 {
            branches.push(resize(adaptive_avg_pool2d(x.clone(), [m, m]), h, w));
        }
        relu(self.norm.forward(conv_layer(
            &self.fuse,
            Tensor::cat(branches, 1),
            Act::Identity,
        ))) // [B, 4C, H, W] → [B, C, H, W]
    }
}

/// DASPP (Eqs. S14–S15): a 1×1 convolution, 3×3 atrous convolutions at each dilation rate and a
/// global-average-pooling branch with a 1×1 convolution, concatenated and fused by a 1×1
/// convolution.
#[derive(Module, Debug)]
pub struct Daspp {
    point: Conv2d,
    atrous: Vec<Conv2d>,
    global: Conv2d,
    fuse: Conv2d,
    norm: Norm,
}

impl Daspp {
    pub fn new(
        cin: usize,
        cout: usize,
        dilations: &[usize],
        norm: NormKind,
        device: &Device,
    ) -> Self {
        Self {
            point: conv(cin, cin, 1, 1, 1, device),
            atrous: dilations
                .iter()
                .map(|&d| conv(cin, cin, 3, 1, d, device))
                .collect(),
            global: conv(cin, cin, 1, 1, 1, device),
            fuse: conv(cin * (dilations.len() + 2), cout, 1, 1, 1, device),
            norm: Norm::new(norm, cout, device),
        }
    }

    /// # Shapes
    /// `[B, C, H, W]` → `[B, Cout, H, W]`
    pub fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let [b, c, h, w] = x.dims();
        let mut branches = vec![conv_layer(&self.point, x.clone(), Act::Relu)];
        for a in &self.atrous {
            branches.push(conv_layer(a, x.clone(), Act::Relu));
        }
        let g = conv_layer(&self.global, x.mean_dim(2).mean_dim(3), Act::Relu); // [B, C, 1, 1]
        branches.push(g.expand([b, c, h, w]));
        self.norm.forward(conv_layer(
            &self.fuse,
            Tensor::cat(branches, 1),
            Act::Identity,
        ))
    }
}

/// One DSMSCE encoder: image `[B, 3, H, W]` → features `[B, out, H/8, W/8]`.
#[derive(Module, Debug)]
pub struct Dsmsce {
    stem: Conv2d,
    stem_norm: Norm,
    stage1: Vec<ResidualBlock>,
    stage2: Vec<ResidualBlock>,
    stage3: Vec<ResidualBlock>,
    pyramid: PyramidPooling,
    daspp: Daspp,
}

impl Dsmsce {
    pub fn new(
        dims: [usize; 3],
        out: usize,
        dilations: &[usize],
        norm: NormKind,
        device: &Device,
    ) -> Self {
        let [d1, d2, d3] = dims;
        Self {
            stem: conv(3, d1, 7, 2, 1, device),
            stem_norm: Norm::new(norm, d1, device),
            stage1: vec![
                ResidualBlock::new(d1, d1, 1, norm, device),
                ResidualBlock::new(d1, d1, 1, norm, device),
            ],
            stage2: vec![
                ResidualBlock::new(d1, d2, 2, norm, device),
                ResidualBlock::new(d2, d2, 1, norm, device),
            ],
            stage3: vec![
                ResidualBlock::new(d2, d3, 2, norm, device),
                ResidualBlock::new(d3, d3, 1, norm, device),
            ],
            pyramid: PyramidPooling::new(d3, norm, device),
            daspp: Daspp::new(d3, out, dilations, norm, device),
        }
    }

    /// # Shapes
    /// `[B, 3, H, W]` (H, W multiples of 8) → `[B, out, H/8, W/8]`
    pub fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let mut x = relu(
            self.stem_norm
                .forward(conv_layer(&self.stem, x, Act::Identity)),
        ); // [B, d1, H/2, W/2]
        for b in self.stage1.iter().chain(&self.stage2).chain(&self.stage3) {
            x = b.forward(x); // → [B, d3, H/8, W/8]
        }
        self.daspp.forward(self.pyramid.forward(x))
    }
}

#[cfg(test)]
mod tests {
    use burn::tensor::Distribution;
    use burn::tensor::module::interpolate;
    use burn::tensor::ops::{InterpolateMode, InterpolateOptions};

    use super::*;

    #[test]
    fn resize_by_matrix_products_is_burns_bilinear_interpolation() {
        let device = Device::flex();
        // The pooled sizes of the pyramid (1, 2, 3) up to odd and even map sizes, an
        // up-and-down mixture, and a plain downscale.
        for (m, n, h, w) in [
            (1, 1, 6, 7),
            (2, 2, 48, 64),
            (3, 3, 47, 61),
            (3, 5, 4, 9),
            (9, 8, 4, 3),
        ] {
            let x = Tensor::<4>::random([2, 3, m, n], Distribution::Normal(0.0, 1.0), &device);
            let want = interpolate(
                x.clone(),
                InterpolateOptions::new(InterpolateMode::Bilinear)
                    .with_align_corners(false)
                    .with_output_size([h, w]),
            );
            let got = resize(x, h, w);
            assert_eq!(got.dims(), [2, 3, h, w]);
            let diff = (got - want).abs().max().into_scalar::<f32>();
            assert!(diff < 1e-5, "{m}x{n} → {h}x{w}: max difference {diff}");
        }
    }

    #[test]
    fn resize_weights_rows_sum_to_one_and_keep_a_constant() {
        for (len, out) in [(1, 5), (2, 7), (3, 48), (7, 3)] {
            let r = resize_weights(len, out);
            for row in r.chunks(len) {
                let s: f32 = row.iter().sum();
                assert!((s - 1.0).abs() < 1e-6, "{len} → {out}: row sums to {s}");
                assert!(row.iter().all(|&v| v >= 0.0));
            }
        }
    }

    #[test]
    fn resize_has_a_gradient() {
        let device = Device::flex().autodiff();
        let x = Tensor::<4>::ones([1, 1, 2, 2], &device).require_grad();
        let y = resize(x.clone(), 5, 3).sum();
        let grads = y.backward();
        let g = x.grad(&grads).expect("a gradient for the input");
        // Each output pixel's weights sum to one, so the input gradients sum to 5·3.
        let total = g.sum().into_scalar::<f32>();
        assert!((total - 15.0).abs() < 1e-4, "{total}");
    }
}
