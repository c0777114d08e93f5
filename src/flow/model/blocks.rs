//! Building blocks shared by the encoders: convolutions with explicit padding, a normalisation
//! switch and the residual block.

use burn::nn::conv::{Conv2d, Conv2dConfig};
use burn::nn::{GroupNorm, GroupNormConfig, InstanceNorm, InstanceNormConfig, PaddingConfig2d};
use burn::prelude::*;
use burn::tensor::activation::relu;

use super::config::NormKind;
use super::host_conv::conv_forward;
use super::host_norm::{group_norm, on_host};
use super::train_norm::group_norm_train;

/// A k×k convolution with `stride` and `dilation`, padded so that stride 1 keeps the size.
/// Padding is explicit: burn's `Same` ignores dilation.
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

/// The bias of `c`, or zeros when it has none: for convolutions whose kernels are stacked into
/// one call of `burn::tensor::module::conv2d`.
///
/// # Shapes
/// → `[Cout]`
pub fn bias_or_zeros(c: &Conv2d) -> Tensor<1> {
    match &c.bias {
        Some(b) => b.val(),
        None => {
            let w = c.weight.val();
            Tensor::zeros([w.dims()[0]], &w.device())
        }
    }
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

    /// Groups, ε, γ and β of the layer; `None` for no normalisation.
    #[allow(clippy::type_complexity)]
    fn params(&self) -> Option<(usize, f64, Option<Tensor<1>>, Option<Tensor<1>>)> {
        let val = |p: &Option<burn::module::Param<Tensor<1>>>| p.as_ref().map(|p| p.val());
        match (&self.instance, &self.group) {
            (Some(n), _) => Some((n.num_channels, n.epsilon, val(&n.gamma), val(&n.beta))),
            (None, Some(n)) => Some((n.num_groups, n.epsilon, val(&n.gamma), val(&n.beta))),
            (None, None) => None,
        }
    }

    /// # Shapes
    /// `[B, C, H, W]` → `[B, C, H, W]`
    pub fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        // The CPU backend normalises on host memory (training through a differentiable
        // operation); anything it declines falls through to burn's layer below.
        if let Some((groups, eps, gamma, beta)) = self.params() {
            let y = match (&gamma, &beta) {
                (Some(g), Some(b)) if x.is_autodiff() => group_norm_train(&x, groups, eps, g, b),
                _ if on_host(&x) && x.dims()[1].is_multiple_of(groups.max(1)) => {
                    group_norm(x.clone(), groups, eps, gamma, beta)
                }
                _ => None,
            };
            if let Some(y) = y {
                return y;
            }
        }
        if let Some(n) = &self.instance {
            n.forward(x)
        } else if let Some(n) = &self.group {
            n.forward(x)
        } else {
            x
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

    /// # Shapes
    /// `[B, Cin, H, W]` → `[B, Cout, H/stride, W/stride]`
    pub fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let y = relu(self.norm1.forward(conv_forward(&self.conv1, x.clone())));
        let y = relu(self.norm2.forward(conv_forward(&self.conv2, y)));
        let skip = match (&self.skip, &self.skip_norm) {
            (Some(c), Some(n)) => n.forward(conv_forward(c, x)),
            _ => x,
        };
        relu(skip + y)
    }
}
