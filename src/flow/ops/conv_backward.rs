//! The convolution of training on the CPU as one tracked operation, `act(W ⋆ x + b)`, and its
//! `Backward`: the output gradient times `act′` (read from the saved output), then the input,
//! kernel and bias gradients of [`crate::flow::kernels::conv`], the first two side by side.

use burn::backend::Flex;
use burn::backend::autodiff::NodeId;
use burn::backend::autodiff::checkpoint::base::Checkpointer;
use burn::backend::autodiff::checkpoint::strategy::NoCheckpointing;
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, Ops, OpsKind, OpsPrep};
use burn::prelude::*;

use super::bridge::{Ad, AdT, FlexT, HostView, from_host};
use crate::flow::kernels::act::Act;
use crate::flow::kernels::conv as kernel;
use crate::flow::kernels::geometry::ConvParams;
use crate::flow::kernels::par;

/// `act(W ⋆ x + b)` as one tracked operation on f32 operands of the autodiff CPU backend (the
/// caller's route), padded within the kernel's reach; `None` if an operand is not on it.
///
/// # Shapes
/// `x` `[B, Cin, H, W]`, `weight` `[Cout, Cin, kh, kw]`, `bias` `[Cout]` → `[B, Cout, H', W']`
pub fn tracked(
    x: &Tensor<4>,
    weight: &Tensor<4>,
    bias: Option<&Tensor<1>>,
    params: ConvParams,
    act: Act,
) -> Option<Tensor<4>> {
    let xp = x.clone().try_into_primitive::<Ad>().ok()?;
    let wp = weight.clone().try_into_primitive::<Ad>().ok()?;
    let bp = match bias {
        Some(b) => Some(b.clone().try_into_primitive::<Ad>().ok()?),
        None => None,
    };
    Some(Tensor::from_primitive::<Ad>(op(xp, wp, bp, params, act)))
}

/// What the backward pass keeps: the input and kernel nodes, the parameters, the activation
/// and, when it has a derivative other than 1, the output it reads `act′` from.
#[derive(Clone, Debug)]
struct ConvState {
    x: NodeId,
    w: NodeId,
    params: ConvParams,
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
        let p = &state.params;
        // The input and kernel gradients are independent products: run side by side, each
        // fills the other's idle threads (a weight gradient has 9 tap tasks for 2 threads).
        let (dx, (dw, db)) = par::join(
            || {
                node_x.as_ref().map(|_| {
                    let [_, _, h, w_in] = x.dims;
                    kernel::input_grad(g_pre, g.dims, w.values(), w.dims, [h, w_in], p).0
                })
            },
            || {
                let dw = node_w
                    .as_ref()
                    .map(|_| kernel::weight_grad(x.values(), x.dims, g_pre, [cout, kh, kw], p));
                let db = node_b.as_ref().map(|_| kernel::bias_grad(g_pre, g.dims));
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

/// The forward pass on host values, registered with the graph.
fn op(x: AdT, w: AdT, b: Option<AdT>, params: ConvParams, act: Act) -> AdT {
    let forward = |x: &AdT, w: &AdT, b: Option<&AdT>| {
        let (xv, wv) = (
            HostView::<4>::new(x.primitive().clone()),
            HostView::<4>::new(w.primitive().clone()),
        );
        let bv = b.map(|b| HostView::<1>::new(b.primitive().clone()));
        let bias = bv.as_ref().map(|b| b.values());
        let (mut y, shape) =
            kernel::conv2d(xv.values(), xv.dims, wv.values(), wv.dims, bias, &params);
        act.apply(&mut y);
        from_host(y, shape)
    };
    let y = forward(&x, &w, b.as_ref());
    match b {
        Some(b) => track(
            HostConv.prepare::<NoCheckpointing>([x.node(), w.node(), b.node()]),
            &x,
            &w,
            params,
            act,
            y,
        ),
        None => track(
            HostConv.prepare::<NoCheckpointing>([x.node(), w.node()]),
            &x,
            &w,
            params,
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
    params: ConvParams,
    act: Act,
    y: FlexT,
) -> AdT {
    match prep.compute_bound().stateful() {
        OpsKind::Tracked(mut prep) => {
            let state = ConvState {
                x: prep.checkpoint(x),
                w: prep.checkpoint(w),
                params,
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
    use super::super::conv::{act_tensor, conv2d};
    use crate::flow::kernels::testing::{Tol, cases};
    use crate::flow::ops::testing::{RandomLayer, assert_tensors_close, random, random_layer};
    use burn::prelude::*;
    use burn::tensor::module::conv2d as burn_conv2d;
    use burn::tensor::ops::ConvOptions;
    use rand::RngExt;

    use super::*;

    /// Output and gradients (input, weight, bias) equal those of Burn's convolution and
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
                let layer = RandomLayer {
                    input: [b, cin, h, w],
                    weight: [cout, cin, k, k],
                    options: ConvOptions::new([1, 1], [p, p], [d, d], 1),
                };
                check(&layer, act, i % 2 == 0, 0);
            }
        }
        // Strided: the stem, the downsampling 3×3 and the 1×1 projection, on even and odd sizes.
        for (cin, cout, k, p, h, w) in [
            (3, 8, 7, 3, 16, 20),
            (6, 9, 3, 1, 11, 14),
            (5, 7, 1, 0, 9, 12),
        ] {
            let layer = RandomLayer {
                input: [2, cin, h, w],
                weight: [cout, cin, k, k],
                options: ConvOptions::new([2, 2], [p, p], [1, 1], 1),
            };
            check(&layer, Act::Relu, true, 1);
        }
    }

    /// Property: random layers (kernels, strides, dilations, per-side paddings within the
    /// kernel's reach, channels, sizes, activations, with and without bias; seeded) give Burn's
    /// output and gradients.
    #[test]
    fn random_training_layers_match_burn() {
        for case in 0..40 {
            let mut r = cases("conv backward vs burn", case);
            let layer = random_layer(&mut r, true);
            let act = [Act::Identity, Act::Relu, Act::Sigmoid, Act::Tanh][case as usize % 4];
            check(&layer, act, r.random_bool(0.7), case);
        }
    }

    fn check(layer: &RandomLayer, act: Act, with_bias: bool, seed: u64) {
        let dev = Device::flex().autodiff();
        let mut r = cases("conv backward inputs", seed);
        let cout = layer.weight[0];
        let x0 = random(&mut r, layer.input, 1.0, &dev);
        let w0 = random(&mut r, layer.weight, 0.3, &dev);
        let b0 = random(&mut r, [cout], 1.0, &dev);
        let out = burn_conv2d(
            x0.clone(),
            w0.clone(),
            Some(b0.clone()),
            layer.options.clone(),
        );
        let weights = random(&mut r, out.dims(), 1.0, &dev);
        let run = |host: bool| {
            let (x, wt, bias) = (
                x0.clone().detach().require_grad(),
                w0.clone().detach().require_grad(),
                b0.clone().detach().require_grad(),
            );
            let b_in = with_bias.then(|| bias.clone());
            let y = if host {
                conv2d(x.clone(), wt.clone(), b_in, layer.options.clone(), act)
            } else {
                act_tensor(
                    act,
                    burn_conv2d(x.clone(), wt.clone(), b_in, layer.options.clone()),
                )
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
        let what = |q: &str| format!("{q} of {layer:?} {act:?} bias {with_bias}");
        let tol = Tol::Scaled(1e-4);
        assert_tensors_close(ya, yb, tol, &what("output"));
        assert_tensors_close(gxa, gxb, tol, &what("input gradient"));
        assert_tensors_close(gwa, gwb, tol, &what("weight gradient"));
        assert_tensors_close(gba, gbb, tol, &what("bias gradient"));
    }

    /// The autodiff device really takes the host operation (not the fallback).
    #[test]
    fn autodiff_tensors_reach_the_host_operation() {
        let dev = Device::flex().autodiff();
        let x = Tensor::<4>::zeros([1, 2, 4, 4], &dev);
        let w = Tensor::<4>::zeros([3, 2, 3, 3], &dev);
        let y = tracked(&x, &w, None, ConvParams::same(1, 1), Act::Relu);
        assert_eq!(y.map(|y| y.dims()), Some([1, 3, 4, 4]));
    }
}
