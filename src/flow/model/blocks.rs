//! Building blocks shared by the encoders (Note S10): convolutions with explicit padding, a
//! normalisation switch and the residual block.

use burn::nn::conv::{Conv2d, Conv2dConfig};
use burn::nn::{GroupNorm, GroupNormConfig, InstanceNorm, InstanceNormConfig, PaddingConfig2d};
use burn::prelude::*;
use burn::tensor::activation::relu;

use super::config::NormKind;
use crate::flow::ops::{self, Act, NormLayer};

/// A k×k convolution with `stride` and `dilation`, padded so that stride 1 keeps the size.
/// Padding is explicit: Burn's `Same` ignores dilation.
pub fn conv(
    cin: usize,
    cout: usize,
    k: usize,
    stride: usize,
    dilation: usize,
    device: &Device,
) -> Conv2d {
    let p = dilation * (k - 1) / 2;
    Conv2dConfig::new([cin, cout], [k, k])
        .with_stride([stride, stride])
        .with_dilation([dilation, dilation])
        .with_padding(PaddingConfig2d::Explicit(p, p, p, p))
        .init(device)
}

/// A normalisation layer chosen by [`NormKind`].
#[derive(Module, Debug)]
pub struct Norm {
    instance: Option<InstanceNorm>,
    group: Option<GroupNorm>,
}

impl Norm {
    pub fn new(kind: NormKind, channels: usize, device: &Device) -> Self {
        match kind {
            NormKind::Instance => Self {
                instance: Some(InstanceNormConfig::new(channels).init(device)),
                group: None,
            },
            NormKind::Group => Self {
                instance: None,
                group: Some(GroupNormConfig::new(8.min(channels), channels).init(device)),
            },
            NormKind::None => Self {
                instance: None,
                group: None,
            },
        }
    }

    /// # Shapes
    /// `[B, C, H, W]` → `[B, C, H, W]`
    pub fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        match (&self.instance, &self.group) {
            (Some(n), _) => ops::norm(NormLayer::Instance(n), x),
            (None, Some(n)) => ops::norm(NormLayer::Group(n), x),
            (None, None) => x,
        }
    }
}

/// Two 3×3 convolutions with a skip connection (a 1×1 projection when the shape changes).
#[derive(Module, Debug)]
pub struct ResidualBlock {
    conv1: Conv2d,
    norm1: Norm,
    conv2: Conv2d,
    norm2: Norm,
    skip: Option<Conv2d>,
    skip_norm: Option<Norm>,
}

impl ResidualBlock {
    pub fn new(cin: usize, cout: usize, stride: usize, norm: NormKind, device: &Device) -> Self {
        let project = stride != 1 || cin != cout;
        Self {
            conv1: conv(cin, cout, 3, stride, 1, device),
            norm1: Norm::new(norm, cout, device),
            conv2: conv(cout, cout, 3, 1, 1, device),
            norm2: Norm::new(norm, cout, device),
            skip: project.then(|| conv(cin, cout, 1, stride, 1, device)),
            skip_norm: project.then(|| Norm::new(norm, cout, device)),
        }
    }

    /// `relu(skip(x) + relu(norm2(conv2(relu(norm1(conv1(x)))))))`
    ///
    /// # Shapes
    /// `[B, Cin, H, W]` → `[B, Cout, H/stride, W/stride]`
    pub fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let layer =
            |c: &Conv2d, n: &Norm, x: Tensor<4>| n.forward(ops::conv_layer(c, x, Act::Identity));
        let y = relu(layer(&self.conv1, &self.norm1, x.clone()));
        let y = relu(layer(&self.conv2, &self.norm2, y));
        let skip = match (&self.skip, &self.skip_norm) {
            (Some(c), Some(n)) => layer(c, n, x),
            _ => x,
        };
        relu(skip + y)
    }
}
