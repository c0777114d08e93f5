//! The convolutions of training (every layer of Notes S9–S10) as one autodiff operation on the
//! CPU backend whose forward and backward passes run the host kernels of [`super::host_conv`]:
//!
//! - forward: `y = W ⋆ x` by channel-first unfolding and one product per band of rows;
//! - `∂L/∂x = W̃ ⋆ ∂L/∂y`, with `W̃[c, o] = W[o, c]` flipped in both axes and the padding
//!   mirrored (`d·(k−1) − p`): the transposed convolution is a convolution (for stride s, of the
//!   output gradient spread onto the stride-1 grid with zeros between);
//! - `∂L/∂W = Σ ∂L/∂y(band) · cols(band)ᵀ`, the forward unfolding reused.
//!
//! - `∂L/∂b = Σ ∂L/∂y` over images and pixels.
//!
//! The bias and the activation that follows the layer ([`Act`]: ReLU, σ or tanh) belong to the
//! same operation: the output is `act(W ⋆ x + b)`, and the backward pass first multiplies the
//! output gradient by `act′`, read from the saved output. That spares the graph a broadcast add
//! and an activation per layer, forward and backward. Grouped convolutions, padding wider than
//! the kernel's reach, other devices and other dtypes keep burn's `conv2d` and activations.

use burn::backend::Flex;
use burn::backend::autodiff::NodeId;
use burn::backend::autodiff::checkpoint::base::Checkpointer;
use burn::backend::autodiff::checkpoint::strategy::NoCheckpointing;
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, Ops, OpsKind, OpsPrep};
use burn::prelude::*;
use burn::tensor::module::conv2d;
use burn::tensor::ops::ConvOptions;

use super::flex_bridge::{Ad, AdT, FlexT, HostView, from_host};
use super::host_conv::{Act, conv_host, weight_grad_host};

/// `act(conv2d(x, weight, bias, options))` under autodiff, through the host kernels when the
/// convolution and the device allow it (see the module notes), else burn's `conv2d`.
///
/// # Shapes
/// `x` `[B, Cin, H, W]`, `weight` `[Cout, Cin, kh, kw]`, `bias` `[Cout]` → `[B, Cout, H', W']`
pub fn conv2d_train(
    x: Tensor<4>,
    weight: Tensor<4>,
    bias: Option<Tensor<1>>,
    options: ConvOptions<2>,
    act: Act,
) -> Tensor<4> {
    let [_, _, kh, kw] = weight.dims();
    let [dy, dx] = options.dilation;
    let mirrored = options.padding[0].0.max(options.padding[0].1) <= dy * (kh - 1)
        && options.padding[1].0.max(options.padding[1].1) <= dx * (kw - 1);
    let f32 = |dtype: burn::tensor::DType| dtype == burn::tensor::DType::F32;
    let suitable = options.groups == 1
        && mirrored
        && x.dims()[1] == weight.dims()[1]
        && f32(x.dtype())
        && f32(weight.dtype())
        && bias.as_ref().is_none_or(|b| f32(b.dtype()));
    if suitable
        && let (Ok(xp), Ok(wp)) = (
            x.clone().try_into_primitive::<Ad>(),
            weight.clone().try_into_primitive::<Ad>(),
        )
    {
        let bp = match bias.clone().map(|b| b.try_into_primitive::<Ad>()) {
            None => Some(None),
            Some(Ok(b)) => Some(Some(b)),
            Some(Err(_)) => None,
        };
        if let Some(bp) = bp {
            return Tensor::<4>::from_primitive::<Ad>(host_conv_op(xp, wp, bp, options, act));
        }
    }
    act.apply_tensor(conv2d(x, weight, bias, options))
}

/// The output gradient of a strided convolution spread back onto the stride-1 grid, zeros in
/// between, so that its transposed convolution is again a convolution.
///
/// # Shapes
/// `[B, C, H', W']` → `[B, C, (H' − 1)·sy + 1, (W' − 1)·sx + 1]`
fn stuff(g: &[f32], [b, c, ho, wo]: [usize; 4], [sy, sx]: [usize; 2]) -> (Vec<f32>, [usize; 4]) {
    let (h1, w1) = ((ho.max(1) - 1) * sy + 1, (wo.max(1) - 1) * sx + 1);
    let mut out = vec![0f32; b * c * h1 * w1];
    for (plane, src) in out.chunks_exact_mut(h1 * w1).zip(g.chunks_exact(ho * wo)) {
        for (y, row) in src.chunks_exact(wo).enumerate() {
            for (x, &v) in row.iter().enumerate() {
                plane[y * sy * w1 + x * sx] = v;
            }
        }
    }
    (out, [b, c, h1, w1])
}

/// The kernel of the transposed convolution: `W̃[c, o, y, x] = W[o, c, kh−1−y, kw−1−x]`.
///
/// # Shapes
/// `[Cout, Cin, kh, kw]` → `[Cin, Cout, kh, kw]`
fn flip_transpose(w: &[f32], [cout, cin, kh, kw]: [usize; 4]) -> Vec<f32> {
    let taps = kh * kw;
    let mut out = vec![0f32; w.len()];
    for (o, kernels) in w.chunks_exact(cin * taps).enumerate() {
        for (c, kernel) in kernels.chunks_exact(taps).enumerate() {
            let dst = &mut out[(c * cout + o) * taps..][..taps];
            for (d, &v) in dst.iter_mut().rev().zip(kernel) {
                *d = v;
            }
        }
    }
    out
}

/// `∂L/∂x` of a convolution with `options`, from its output gradient `g` `[B, Cout, H', W']`,
/// its kernel `w` `[Cout, Cin, kh, kw]` and its input size `[H, W]`: the convolution of the
/// (stride-spread) gradient by the flipped, transposed kernel with the padding mirrored.
///
/// # Shapes
/// → `[B, Cin, H, W]`
fn input_grad(
    g: &[f32],
    gs: [usize; 4],
    w: &[f32],
    [cout, cin, kh, kw]: [usize; 4],
    [h, w_in]: [usize; 2],
    options: &ConvOptions<2>,
) -> (Vec<f32>, [usize; 4]) {
    let [dy, dx] = options.dilation;
    let (py, px) = (dy * (kh - 1), dx * (kw - 1));
    // Input rows and columns past the last window (stride > 1) get zero gradient from extra end
    // padding.
    let [sy, sx] = options.stride;
    let extra =
        |size: usize, (p0, p1): (usize, usize), span: usize, s: usize| (size + p0 + p1 - span) % s;
    let (ey, ex) = (
        extra(h, options.padding[0], py + 1, sy),
        extra(w_in, options.padding[1], px + 1, sx),
    );
    let mirrored = ConvOptions::new_with_padding(
        [1, 1],
        [
            (py - options.padding[0].0, py - options.padding[0].1 + ey),
            (px - options.padding[1].0, px - options.padding[1].1 + ex),
        ],
        options.dilation,
        1,
    );
    let wt = flip_transpose(w, [cout, cin, kh, kw]);
    let ws = [cin, cout, kh, kw];
    if sy == 1 && sx == 1 {
        conv_host(g, gs, &wt, ws, None, &mirrored)
    } else {
        let (spread, ss) = stuff(g, gs, [sy, sx]);
        conv_host(&spread, ss, &wt, ws, None, &mirrored)
    }
}

/// What the backward pass of [`host_conv_op`] keeps: the input and kernel nodes, the options,
/// the activation and, when it has a derivative other than 1, the output it reads `act′` from.
#[derive(Clone, Debug)]
struct ConvState {
    x: NodeId,
    w: NodeId,
    options: ConvOptions<2>,
    act: Act,
    y: Option<FlexT>,
}

#[derive(Debug)]
struct HostConv;

/// Parents: input, kernel, and the bias when `N` is 3.
impl<const N: usize> Backward<Flex, N> for HostConv {
    type State = ConvState;

    fn backward(
        self,
        ops: Ops<Self::State, N>,
        grads: &mut Gradients,
        checkpointer: &mut Checkpointer,
    ) {
        let (node_x, node_w) = (ops.parents[0].clone(), ops.parents[1].clone());
        let node_b = ops.parents.get(2).cloned().flatten();
        let g = HostView::<4>::new(grads.consume::<Flex>(&ops.node));
        let state = ops.state;
        let x = HostView::<4>::new(checkpointer.retrieve_node_output(state.x));
        let w = HostView::<4>::new(checkpointer.retrieve_node_output(state.w));
        // ∂L/∂(W ⋆ x + b) = ∂L/∂y · act′, from the saved output.
        let scaled: Option<Vec<f32>> = state.y.map(|y| {
            let y = HostView::<4>::new(y);
            state.act.backward(y.values(), g.values())
        });
        let g_pre = scaled.as_deref().unwrap_or(g.values());
        let [cout, _, kh, kw] = w.dims;
        // The input and kernel gradients are independent products: run side by side, each
        // fills the other's idle threads (a weight gradient has 9 tap tasks for 2 threads).
        let (dx, (dw, db)) = rayon::join(
            || {
                node_x.as_ref().map(|_| {
                    let [_, _, h, w_in] = x.dims;
                    input_grad(g_pre, g.dims, w.values(), w.dims, [h, w_in], &state.options).0
                })
            },
            || {
                let dw = node_w.as_ref().map(|_| {
                    weight_grad_host(x.values(), x.dims, g_pre, [cout, kh, kw], &state.options)
                });
                let db = node_b.as_ref().map(|_| {
                    let hw = g.dims[2] * g.dims[3];
                    let mut db = vec![0f32; cout];
                    for (i, plane) in g_pre.chunks_exact(hw.max(1)).enumerate() {
                        db[i % cout] += plane.iter().sum::<f32>();
                    }
                    db
                });
                (dw, db)
            },
        );
        if let (Some(node), Some(dx)) = (node_x, dx) {
            grads.register::<Flex>(node.id, from_host(dx, x.dims));
        }
        if let (Some(node), Some(dw)) = (node_w, dw) {
            grads.register::<Flex>(node.id, from_host(dw, w.dims));
        }
        if let (Some(node), Some(db)) = (node_b, db) {
            grads.register::<Flex>(node.id, from_host(db, [cout]));
        }
    }
}

/// `act(W ⋆ x + b)` as one tracked operation (f32 operands, checked by the caller).
fn host_conv_op(x: AdT, w: AdT, b: Option<AdT>, options: ConvOptions<2>, act: Act) -> AdT {
    let forward = |x: &AdT, w: &AdT, b: Option<&AdT>| {
        let (xv, wv) = (
            HostView::<4>::new(x.primitive().clone()),
            HostView::<4>::new(w.primitive().clone()),
        );
        let bv = b.map(|b| HostView::<1>::new(b.primitive().clone()));
        let bias = bv.as_ref().map(|b| b.values());
        let (mut y, shape) = conv_host(xv.values(), xv.dims, wv.values(), wv.dims, bias, &options);
        act.apply(&mut y);
        from_host(y, shape)
    };
    let y = forward(&x, &w, b.as_ref());
    match b {
        Some(b) => track(
            HostConv.prepare::<NoCheckpointing>([x.node(), w.node(), b.node()]),
            &x,
            &w,
            options,
            act,
            y,
        ),
        None => track(
            HostConv.prepare::<NoCheckpointing>([x.node(), w.node()]),
            &x,
            &w,
            options,
            act,
            y,
        ),
    }
}

/// Registers the computed output `y` with the graph (and what its backward pass needs).
fn track<const N: usize>(
    prep: OpsPrep<HostConv, Flex, ConvState, NoCheckpointing, N>,
    x: &AdT,
    w: &AdT,
    options: ConvOptions<2>,
    act: Act,
    y: FlexT,
) -> AdT {
    match prep.compute_bound().stateful() {
        OpsKind::Tracked(mut prep) => {
            let state = ConvState {
                x: prep.checkpoint(x),
                w: prep.checkpoint(w),
                options,
                act,
                y: (act != Act::Identity).then(|| y.clone()),
            };
            prep.finish(state, y)
        }
        OpsKind::UnTracked(prep) => prep.finish(y),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::Distribution;

    /// Output and gradients (input, weight, bias) equal those of burn's convolution and
    /// activation, for a padded 3×3, a dilated one wider than the map, a 7×7, a 1×1 and strided
    /// ones, each activation, with a loss that weights every output differently.
    #[test]
    fn host_training_convolution_matches_burn() {
        let acts = [Act::Identity, Act::Relu, Act::Sigmoid, Act::Tanh];
        // (cin, cout, k, dilation, pad, h, w, batch)
        for (i, (cin, cout, k, d, p, h, w, b)) in [
            (5, 7, 3, 1, 1, 9, 11, 2),
            (6, 4, 3, 6, 6, 5, 7, 1),
            (2, 8, 7, 1, 3, 10, 12, 2),
            (9, 5, 1, 1, 0, 6, 8, 2),
            (16, 24, 3, 1, 1, 40, 52, 1),
        ]
        .into_iter()
        .enumerate()
        {
            for act in acts {
                check(cin, cout, k, d, p, 1, h, w, b, act, i % 2 == 0);
            }
        }
        // Strided: the stem, the downsampling 3×3 and the 1×1 projection, on even and odd sizes.
        for (cin, cout, k, p, h, w) in [
            (3, 8, 7, 3, 16, 20),
            (6, 9, 3, 1, 11, 14),
            (5, 7, 1, 0, 9, 12),
        ] {
            check(cin, cout, k, 1, p, 2, h, w, 2, Act::Relu, true);
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn check(
        cin: usize,
        cout: usize,
        k: usize,
        d: usize,
        p: usize,
        s: usize,
        h: usize,
        w: usize,
        b: usize,
        act: Act,
        with_bias: bool,
    ) {
        let dev = Device::flex().autodiff();
        {
            let x0 = Tensor::<4>::random([b, cin, h, w], Distribution::Normal(0.0, 1.0), &dev);
            let w0 = Tensor::<4>::random([cout, cin, k, k], Distribution::Normal(0.0, 0.3), &dev);
            let b0 = Tensor::<1>::random([cout], Distribution::Normal(0.0, 1.0), &dev);
            let opts = ConvOptions::new([s, s], [p, p], [d, d], 1);
            let weights = Tensor::<4>::random(
                [
                    b,
                    cout,
                    (h + 2 * p - d * (k - 1) - 1) / s + 1,
                    (w + 2 * p - d * (k - 1) - 1) / s + 1,
                ],
                Distribution::Normal(0.0, 1.0),
                &dev,
            );
            let run = |host: bool| {
                let (x, wt, bias) = (
                    x0.clone().detach().require_grad(),
                    w0.clone().detach().require_grad(),
                    b0.clone().detach().require_grad(),
                );
                let b_in = with_bias.then(|| bias.clone());
                let y = if host {
                    conv2d_train(x.clone(), wt.clone(), b_in, opts.clone(), act)
                } else {
                    act.apply_tensor(conv2d(x.clone(), wt.clone(), b_in, opts.clone()))
                };
                let g = (y.clone() * weights.clone()).sum().backward();
                let grad = |t: &Tensor<4>| t.grad(&g).expect("gradient");
                (
                    y.inner(),
                    grad(&x),
                    grad(&wt),
                    bias.grad(&g)
                        .unwrap_or_else(|| Tensor::zeros([cout], &Device::flex())),
                )
            };
            let (ya, gxa, gwa, gba) = run(true);
            let (yb, gxb, gwb, gbb) = run(false);
            let close = |a: Tensor<4>, b: Tensor<4>, what: &str| {
                let scale: f32 = b.clone().abs().max().into_scalar();
                let diff: f32 = (a - b).abs().max().into_scalar();
                assert!(
                    diff <= 1e-4 * scale.max(1.0),
                    "{cin}->{cout} k{k} d{d} s{s} {act:?} bias {with_bias}: {what} off by {diff}"
                );
            };
            close(ya, yb, "output");
            close(gxa, gxb, "input gradient");
            close(gwa, gwb, "weight gradient");
            close(
                gba.reshape([1, cout, 1, 1]),
                gbb.reshape([1, cout, 1, 1]),
                "bias gradient",
            );
        }
    }

    /// The autodiff device really takes the host operation (not the fallback).
    #[test]
    fn autodiff_tensors_reach_the_host_operation() {
        let dev = Device::flex().autodiff();
        let x = Tensor::<4>::zeros([1, 2, 4, 4], &dev);
        assert!(x.try_into_primitive::<Ad>().is_ok());
    }
}
