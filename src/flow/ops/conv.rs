//! The convolution of every layer of Notes S9–S10, with its bias and the activation that
//! follows it (ReLU, σ or tanh), as one operation: `act(W ⋆ x + b)`. Plain CPU tensors run the
//! host kernel ([`crate::flow::kernels::conv`]); training on the CPU runs it inside one tracked
//! operation ([`super::conv_backward`]), so the graph holds one node per layer, not a
//! convolution, a broadcast add and an activation; other devices keep Burn's `conv2d` and
//! activations. Grouped convolutions (none in the network) keep Burn's too.

use burn::nn::PaddingConfig2d;
use burn::nn::conv::Conv2d;
use burn::prelude::*;
use burn::tensor::activation::{relu, sigmoid, tanh};
use burn::tensor::module::conv2d as burn_conv2d;
use burn::tensor::ops::ConvOptions;

use super::bridge::HostView;
use super::route::{Operand, Route};
use crate::flow::kernels::act::Act;
use crate::flow::kernels::conv as kernel;
use crate::flow::kernels::geometry::ConvParams;

/// `act(c.forward(x))`: a layer and its activation as one operation.
///
/// # Shapes
/// `[B, Cin, H, W]` → `[B, Cout, H', W']`
pub fn conv_layer(c: &Conv2d, x: Tensor<4>, act: Act) -> Tensor<4> {
    match options(c) {
        Some(o) => conv2d(x, c.weight.val(), c.bias.as_ref().map(|b| b.val()), o, act),
        None => act_tensor(act, c.forward(x)),
    }
}

/// Layers that read the same input and share their stride, padding and dilation, as one
/// convolution with their kernels stacked, split after: `[act(c.forward(x)) for c in layers]`.
///
/// # Shapes
/// `[B, Cin, H, W]` → `N` × `[B, Cout_i, H', W']`
pub fn conv_stacked<const N: usize>(
    layers: [&Conv2d; N],
    x: Tensor<4>,
    act: Act,
) -> [Tensor<4>; N] {
    let opts = layers.map(options);
    let stackable = opts.iter().all(|o| o.is_some() && *o == opts[0])
        && layers
            .iter()
            .all(|c| c.weight.dims()[1..] == layers[0].weight.dims()[1..]);
    let (true, Some(Some(o))) = (stackable, opts.first().cloned()) else {
        return layers.map(|c| conv_layer(c, x.clone(), act));
    };
    let y = conv2d(
        x,
        Tensor::cat(layers.iter().map(|c| c.weight.val()).collect(), 0),
        Some(Tensor::cat(
            layers.iter().map(|c| bias_or_zeros(c)).collect(),
            0,
        )),
        o,
        act,
    ); // [B, Σ Cout_i, H', W']
    let mut start = 0;
    layers.map(|c| {
        let n = c.weight.dims()[0];
        start += n;
        y.clone().narrow(1, start - n, n)
    })
}

/// `act(burn::tensor::module::conv2d(x, weight, bias, options))`, on the route of its operands.
///
/// # Shapes
/// `x` `[B, Cin, H, W]`, `weight` `[Cout, Cin, kh, kw]`, `bias` `[Cout]` → `[B, Cout, H', W']`
pub fn conv2d(
    x: Tensor<4>,
    weight: Tensor<4>,
    bias: Option<Tensor<1>>,
    options: ConvOptions<2>,
    act: Act,
) -> Tensor<4> {
    let route = Route::of(
        [Operand::of(&x), Operand::of(&weight)]
            .into_iter()
            .chain(bias.as_ref().map(Operand::of)),
    );
    let ungrouped = options.groups == 1 && weight.dims()[1] == x.dims()[1];
    let y = match route {
        Route::Host if ungrouped => host(&x, &weight, bias.as_ref(), &options, act),
        Route::HostAutodiff if ungrouped && within_reach(&weight, &options) => {
            super::conv_backward::tracked(&x, &weight, bias.as_ref(), params(&options), act)
        }
        _ => None,
    };
    y.unwrap_or_else(|| act_tensor(act, burn_conv2d(x, weight, bias, options)))
}

/// The bias of `c`, or zeros when it has none: for convolutions whose kernels are stacked.
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

/// The activation with Burn's tensor operations (any device, differentiable).
pub fn act_tensor(act: Act, t: Tensor<4>) -> Tensor<4> {
    match act {
        Act::Identity => t,
        Act::Relu => relu(t),
        Act::Sigmoid => sigmoid(t),
        Act::Tanh => tanh(t),
    }
}

/// The host kernels' parameters of `options` (groups are checked by the caller).
pub fn params(options: &ConvOptions<2>) -> ConvParams {
    ConvParams {
        stride: options.stride,
        padding: options.padding,
        dilation: options.dilation,
    }
}

/// The options of an ungrouped layer with explicit padding; `None` for any other layer.
fn options(c: &Conv2d) -> Option<ConvOptions<2>> {
    match c.padding {
        PaddingConfig2d::Explicit(top, left, bottom, right) if c.groups == 1 => Some(
            ConvOptions::new_with_padding(c.stride, [(top, bottom), (left, right)], c.dilation, 1),
        ),
        _ => None,
    }
}

/// Whether no side is padded beyond the kernel's reach `d·(k − 1)`, so that the input gradient
/// is a convolution with the padding mirrored.
fn within_reach(weight: &Tensor<4>, options: &ConvOptions<2>) -> bool {
    let [_, _, kh, kw] = weight.dims();
    let [dy, dx] = options.dilation;
    options.padding[0].0.max(options.padding[0].1) <= dy * (kh - 1)
        && options.padding[1].0.max(options.padding[1].1) <= dx * (kw - 1)
}

/// The forward pass on the host kernel, reading the tensors in place; `None` if one cannot be
/// read (not reached for operands on the host route).
fn host(
    x: &Tensor<4>,
    weight: &Tensor<4>,
    bias: Option<&Tensor<1>>,
    options: &ConvOptions<2>,
    act: Act,
) -> Option<Tensor<4>> {
    let xv = HostView::of(x.clone())?;
    let wv = HostView::of(weight.clone())?;
    let bv = match bias {
        Some(b) => Some(HostView::of(b.clone())?),
        None => None,
    };
    let b = bv.as_ref().map(|b| b.values());
    let (mut out, shape) = kernel::conv2d(
        xv.values(),
        xv.dims,
        wv.values(),
        wv.dims,
        b,
        &params(options),
    );
    act.apply(&mut out);
    Some(Tensor::from_data(TensorData::new(out, shape), &x.device()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flow::kernels::testing::{Tol, cases};
    use crate::flow::kernels::unfold;
    use crate::flow::ops::testing::{assert_tensors_close, random, random_layer};
    use burn::nn::conv::Conv2dConfig;
    use burn::tensor::Distribution;
    use rand::RngExt;

    /// The host kernels (unfolded and shifted products) give Burn's numbers for every kind of
    /// convolution in the network: 3×3, strided, dilated beyond the image, 7×7, 1×1 with and
    /// without stride, no bias, asymmetric padding, batches, and maps smaller than the kernel.
    #[test]
    fn host_convolution_matches_burn() {
        let dev = Device::flex();
        // (cin, cout, kernel, stride, dilation, padding (top, bottom, left, right), h, w, batch, bias)
        let cases = [
            (5, 7, 3, 1, 1, (1, 1, 1, 1), 9, 11, 2, true),
            (4, 6, 3, 2, 1, (1, 1, 1, 1), 10, 13, 1, true),
            (3, 8, 7, 2, 1, (3, 3, 3, 3), 16, 20, 2, true),
            (6, 6, 3, 1, 6, (6, 6, 6, 6), 5, 7, 1, true),
            (6, 5, 3, 1, 18, (18, 18, 18, 18), 4, 6, 2, false),
            (9, 4, 1, 1, 1, (0, 0, 0, 0), 6, 8, 2, true),
            (9, 4, 1, 2, 1, (0, 0, 0, 0), 7, 9, 1, true),
            // 1×1 with end padding only: not a plain product of the input.
            (5, 7, 1, 1, 1, (0, 2, 0, 1), 9, 11, 2, true),
            (2, 3, 7, 1, 1, (3, 3, 3, 3), 3, 4, 1, true),
            (3, 4, 3, 1, 1, (0, 2, 1, 0), 6, 5, 1, true),
            (2, 3, 3, 3, 2, (0, 0, 0, 0), 12, 14, 1, false),
            // More channels: odd sizes, asymmetric and no padding, 1×1 maps.
            (8, 9, 3, 1, 1, (1, 1, 1, 1), 7, 5, 2, true),
            (12, 8, 3, 1, 1, (0, 2, 1, 0), 5, 6, 1, false),
            (8, 8, 3, 1, 1, (1, 1, 1, 1), 1, 1, 1, true),
            (9, 10, 3, 1, 1, (0, 0, 0, 0), 3, 8, 2, true),
            (16, 24, 3, 1, 1, (1, 1, 1, 1), 23, 31, 1, true),
        ];
        for (cin, cout, k, s, d, (pt, pb, pl, pr), h, w, b, with_bias) in cases {
            let x = Tensor::<4>::random([b, cin, h, w], Distribution::Normal(0.0, 1.0), &dev);
            let wt = Tensor::<4>::random([cout, cin, k, k], Distribution::Normal(0.0, 1.0), &dev);
            let bias = with_bias
                .then(|| Tensor::<1>::random([cout], Distribution::Normal(0.0, 1.0), &dev));
            let opts = ConvOptions::new_with_padding([s, s], [(pt, pb), (pl, pr)], [d, d], 1);
            let want = burn_conv2d(x.clone(), wt.clone(), bias.clone(), opts.clone());
            let got = conv2d(x, wt, bias, opts, Act::Identity);
            let what = format!("case {cin} {cout} {k} {s} {d}");
            assert_tensors_close(got, want, Tol::Abs(1e-4), &what);
        }
    }

    /// Property: random layers (channels on both sides of the shifted-product threshold, odd
    /// and even kernels, strides, dilations, per-side paddings beyond the kernel's reach, map
    /// sizes, every activation; seeded) give Burn's convolution and activation.
    #[test]
    fn random_layers_match_burn() {
        let dev = Device::flex();
        for case in 0..60 {
            let mut r = cases("conv forward vs burn", case);
            let layer = random_layer(&mut r, false);
            let x = random(&mut r, layer.input, 1.0, &dev);
            let w = random(&mut r, layer.weight, 0.5, &dev);
            let bias = r
                .random_bool(0.7)
                .then(|| random(&mut r, [layer.weight[0]], 1.0, &dev));
            let act = [Act::Identity, Act::Relu, Act::Sigmoid, Act::Tanh][case as usize % 4];
            let want = act_tensor(
                act,
                burn_conv2d(x.clone(), w.clone(), bias.clone(), layer.options.clone()),
            );
            let got = conv2d(x, w, bias, layer.options.clone(), act);
            let what = format!("case {case}: {layer:?} {act:?}");
            assert_tensors_close(got, want, Tol::Scaled(1e-4), &what);
        }
    }

    /// A map larger than one band (several bands per image, on several threads) still matches.
    #[test]
    fn host_convolution_matches_burn_across_bands() {
        let dev = Device::flex();
        let (cin, cout, h, w) = (64, 16, 70, 90);
        let x = Tensor::<4>::random([2, cin, h, w], Distribution::Normal(0.0, 1.0), &dev);
        let wt = Tensor::<4>::random([cout, cin, 3, 3], Distribution::Normal(0.0, 0.1), &dev);
        let bias = Tensor::<1>::random([cout], Distribution::Normal(0.0, 1.0), &dev);
        let opts = ConvOptions::new([1, 1], [1, 1], [1, 1], 1);
        let g = crate::flow::kernels::geometry::Geometry::new(
            [2, cin, h, w],
            [cout, cin, 3, 3],
            &params(&opts),
        );
        assert!(unfold::bands(&g).1 > 2, "one band only");
        let want = burn_conv2d(x.clone(), wt.clone(), Some(bias.clone()), opts.clone());
        let got = conv2d(x, wt, Some(bias), opts, Act::Identity);
        assert_tensors_close(got, want, Tol::Abs(1e-4), "across bands");
    }

    /// The layer form uses the layer's own stride, dilation and explicit padding, on the plain
    /// and the autodiff device; stacked layers give each layer's own output.
    #[test]
    fn layer_forms_match_the_layer() {
        for dev in [Device::flex(), Device::flex().autodiff()] {
            let layer = Conv2dConfig::new([4, 6], [3, 3])
                .with_stride([2, 2])
                .with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1))
                .init(&dev);
            let x = Tensor::<4>::random([1, 4, 12, 10], Distribution::Normal(0.0, 1.0), &dev);
            let y = conv_layer(&layer, x.clone(), Act::Identity);
            assert_eq!(y.is_autodiff(), dev.is_autodiff());
            assert_tensors_close(y, layer.forward(x), Tol::Abs(1e-4), "layer");
            let same = |cout| {
                Conv2dConfig::new([4, cout], [3, 3])
                    .with_dilation([2, 2])
                    .with_padding(PaddingConfig2d::Explicit(2, 2, 2, 2))
                    .init(&dev)
            };
            let (a, b) = (same(3), same(5));
            let x = Tensor::<4>::random([2, 4, 9, 9], Distribution::Normal(0.0, 1.0), &dev);
            let [ya, yb] = conv_stacked([&a, &b], x.clone(), Act::Tanh);
            assert_tensors_close(ya, tanh(a.forward(x.clone())), Tol::Abs(1e-5), "stacked a");
            assert_tensors_close(yb, tanh(b.forward(x)), Tol::Abs(1e-5), "stacked b");
        }
    }
}
