//! Test support for the operations: seeded random tensors and layers, and tensors compared
//! through the one tolerance check of [`crate::flow::kernels::testing`].

use burn::prelude::*;
use burn::tensor::ops::ConvOptions;
use rand::RngExt;

use crate::flow::kernels::testing::{Tol, assert_close, values};
use crate::rng::Rng;

/// A tensor's values, in row-major order.
pub fn host_values<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    let t = if t.is_autodiff() { t.inner() } else { t };
    t.into_data().try_to_vec::<f32>().unwrap_or_default()
}

/// Asserts equal shapes and values within `tol` (see [`assert_close`]).
#[track_caller]
pub fn assert_tensors_close<const D: usize>(got: Tensor<D>, want: Tensor<D>, tol: Tol, what: &str) {
    assert_eq!(got.dims(), want.dims(), "{what}: shapes differ");
    assert_close(&host_values(got), &host_values(want), tol, what);
}

/// A tensor of seeded uniform values with standard deviation `sigma`.
pub fn random<const D: usize>(
    r: &mut Rng,
    shape: [usize; D],
    sigma: f32,
    dev: &Device,
) -> Tensor<D> {
    let n = shape.iter().product();
    Tensor::from_data(TensorData::new(values(r, n, sigma), shape), dev)
}

/// One random convolution.
#[derive(Clone, Debug)]
pub struct RandomLayer {
    pub input: [usize; 4],
    pub weight: [usize; 4],
    pub options: ConvOptions<2>,
}

/// A random ungrouped convolution with a non-empty output: 1–5 wide kernels (odd and even),
/// strides 1–3, dilations 1–3, each side padded up to the kernel's reach (and, unless
/// `within_reach`, sometimes beyond), input channels on both sides of the shifted-product
/// threshold (16), maps from 1 pixel up.
pub fn random_layer(r: &mut Rng, within_reach: bool) -> RandomLayer {
    let (kh, kw) = (r.random_range(1..=5), r.random_range(1..=5));
    let stride = [r.random_range(1..=3), r.random_range(1..=3)];
    let dilation = [r.random_range(1..=3), r.random_range(1..=3)];
    let beyond = if within_reach {
        0
    } else {
        r.random_range(0..=2)
    };
    let mut pad = |reach: usize| {
        (
            r.random_range(0..=reach + beyond),
            r.random_range(0..=reach + beyond),
        )
    };
    let padding = [pad(dilation[0] * (kh - 1)), pad(dilation[1] * (kw - 1))];
    // The smallest side whose padded size covers the kernel's span.
    let least = |k: usize, d: usize, (p0, p1): (usize, usize)| {
        (d * (k - 1) + 1).saturating_sub(p0 + p1).max(1)
    };
    let h = least(kh, dilation[0], padding[0]) + r.random_range(0..=14);
    let w = least(kw, dilation[1], padding[1]) + r.random_range(0..=14);
    let cin = if r.random_bool(0.3) {
        r.random_range(16..=24)
    } else {
        r.random_range(1..=8)
    };
    let (b, cout) = (r.random_range(1..=2), r.random_range(1..=10));
    RandomLayer {
        input: [b, cin, h, w],
        weight: [cout, cin, kh, kw],
        options: ConvOptions::new_with_padding(stride, padding, dilation, 1),
    }
}
