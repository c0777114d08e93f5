//! Convex 8× upsampling (Note S9) as one operation: on the host kernel
//! ([`crate::flow::kernels::upsample`]) for plain CPU tensors, as one tracked operation with its
//! `Backward` in training on the CPU, and as Burn's tensor operations (a softmax, an unfold, a
//! product, a sum and a permutation) elsewhere.

use burn::backend::Flex;
use burn::backend::autodiff::NodeId;
use burn::backend::autodiff::checkpoint::base::Checkpointer;
use burn::backend::autodiff::checkpoint::strategy::NoCheckpointing;
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, Ops, OpsKind};
use burn::prelude::*;
use burn::tensor::activation::softmax;
use burn::tensor::module::unfold4d;
use burn::tensor::ops::UnfoldOptions;

use super::bridge::{Ad, AdT, HostView, from_host};
use super::route::{Operand, Route};
use crate::flow::kernels::upsample::{backward, forward};

/// Every full-resolution flow vector as the softmax-weighted convex combination of 8× the flow
/// at the 3×3 coarse neighbours of its cell; mask channel `k·64 + s` weighs neighbour k of
/// sub-pixel s. The softmax subtracts the maximum, so huge logits stay finite.
///
/// # Shapes
/// `flow` `[B, 2, H, W]` (1/8-resolution pixels), `mask` `[B, 576, H, W]` → `[B, 2, 8H, 8W]`
/// (full-resolution pixels)
pub fn convex_upsample(flow: Tensor<4>, mask: Tensor<4>) -> Tensor<4> {
    let [b, c, h, w] = flow.dims();
    let fits = c == 2 && mask.dims() == [b, 576, h, w];
    let up = match Route::of([Operand::of(&flow), Operand::of(&mask)]) {
        Route::Host if fits => host(&flow, &mask),
        Route::HostAutodiff if fits => tracked(&flow, &mask),
        _ => None,
    };
    up.unwrap_or_else(|| convex_upsample_tensor(flow, mask))
}

/// The same as Burn's tensor operations, for any device.
///
/// # Shapes
/// `flow` `[B, 2, H, W]`, `mask` `[B, 576, H, W]` → `[B, 2, 8H, 8W]`
pub fn convex_upsample_tensor(flow: Tensor<4>, mask: Tensor<4>) -> Tensor<4> {
    let [b, _, h, w] = flow.dims();
    let mask = softmax(mask.reshape([b, 1, 9, 64, h * w]), 2);
    let neighbours = unfold4d(
        flow.mul_scalar(8.0),
        [3, 3],
        UnfoldOptions::new([1, 1], [1, 1], [1, 1]),
    )
    .reshape([b, 2, 9, 1, h * w]); // [B, 2·9, H·W] → [B, 2, 9, 1, H·W]
    (mask * neighbours)
        .sum_dim(2) // [B, 2, 1, 64, H·W]
        .reshape([b, 2, 8, 8, h, w])
        .permute([0, 1, 4, 2, 5, 3])
        .reshape([b, 2, 8 * h, 8 * w])
}

/// On the host kernel, for inference.
fn host(flow: &Tensor<4>, mask: &Tensor<4>) -> Option<Tensor<4>> {
    let [b, _, h, w] = flow.dims();
    let fv = HostView::of(flow.clone())?;
    let mv = HostView::of(mask.clone())?;
    let out = forward(fv.values(), mv.values(), [b, h, w]);
    Some(Tensor::from_data(
        TensorData::new(out, [b, 2, 8 * h, 8 * w]),
        &flow.device(),
    ))
}

/// As one tracked operation on the autodiff CPU backend.
fn tracked(flow: &Tensor<4>, mask: &Tensor<4>) -> Option<Tensor<4>> {
    let fp = flow.clone().try_into_primitive::<Ad>().ok()?;
    let mp = mask.clone().try_into_primitive::<Ad>().ok()?;
    Some(Tensor::from_primitive::<Ad>(op(fp, mp)))
}

#[derive(Debug)]
struct HostUpsample;

impl Backward<Flex, 2> for HostUpsample {
    type State = (NodeId, NodeId);

    fn backward(
        self,
        ops: Ops<Self::State, 2>,
        grads: &mut Gradients,
        checkpointer: &mut Checkpointer,
    ) {
        let [node_f, node_m] = ops.parents;
        let g = HostView::<4>::new(grads.consume::<Flex>(&ops.node));
        let (f_state, m_state) = ops.state;
        let f = HostView::<4>::new(checkpointer.retrieve_node_output(f_state));
        let m = HostView::<4>::new(checkpointer.retrieve_node_output(m_state));
        let [b, _, h, w] = f.dims;
        let (dflow, dmask) = backward(f.values(), m.values(), g.values(), [b, h, w]);
        if let Some(node) = node_f {
            grads.register::<Flex>(node.id, from_host(dflow, [b, 2, h, w]));
        }
        if let Some(node) = node_m {
            grads.register::<Flex>(node.id, from_host(dmask, [b, 576, h, w]));
        }
    }
}

fn op(flow: AdT, mask: AdT) -> AdT {
    let run = |flow: &AdT, mask: &AdT| {
        let f = HostView::<4>::new(flow.primitive().clone());
        let m = HostView::<4>::new(mask.primitive().clone());
        let [b, _, h, w] = f.dims;
        from_host(
            forward(f.values(), m.values(), [b, h, w]),
            [b, 2, 8 * h, 8 * w],
        )
    };
    match HostUpsample
        .prepare::<NoCheckpointing>([flow.node(), mask.node()])
        .compute_bound()
        .stateful()
    {
        OpsKind::Tracked(mut prep) => {
            let f_state = prep.checkpoint(&flow);
            let m_state = prep.checkpoint(&mask);
            let y = run(&flow, &mask);
            prep.finish((f_state, m_state), y)
        }
        OpsKind::UnTracked(prep) => prep.finish(run(&flow, &mask)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flow::kernels::testing::{Tol, cases};
    use crate::flow::ops::testing::{assert_tensors_close, random};
    use rand::RngExt;

    /// Property: on random map sizes and logits (seeded, borders included), the output and
    /// both gradients of the tracked operation equal the tensor form's, and the plain
    /// (inference) form gives the same output.
    #[test]
    fn host_upsampling_matches_the_tensor_form() {
        let dev = Device::flex().autodiff();
        for case in 0..10 {
            let mut r = cases("upsampling vs tensor form", case);
            // Case 0 is the former fixed case.
            let (b, h, w) = if case == 0 {
                (2, 3, 5)
            } else {
                (
                    r.random_range(1..=2),
                    r.random_range(1..=5),
                    r.random_range(1..=7),
                )
            };
            let f0 = random(&mut r, [b, 2, h, w], 2.0, &dev);
            let m0 = random(&mut r, [b, 576, h, w], 3.0, &dev);
            let weights = random(&mut r, [b, 2, 8 * h, 8 * w], 1.0, &dev);
            let run = |host: bool| {
                let (f, m) = (
                    f0.clone().detach().require_grad(),
                    m0.clone().detach().require_grad(),
                );
                let y = if host {
                    convex_upsample(f.clone(), m.clone())
                } else {
                    convex_upsample_tensor(f.clone(), m.clone())
                };
                let g = (y.clone() * weights.clone()).sum().backward();
                (
                    y.inner(),
                    f.grad(&g).expect("flow gradient"),
                    m.grad(&g).expect("mask gradient"),
                )
            };
            let (ya, fa, ma) = run(true);
            let (yb, fb, mb) = run(false);
            let what = |q: &str| format!("case {case} {q}: {b}x{h}x{w}");
            assert_tensors_close(ya.clone(), yb, Tol::Abs(1e-4), &what("output"));
            assert_tensors_close(fa, fb, Tol::Abs(1e-3), &what("flow gradient"));
            assert_tensors_close(ma, mb, Tol::Abs(1e-4), &what("mask gradient"));
            let plain = convex_upsample(f0.clone().inner(), m0.clone().inner());
            assert_tensors_close(plain, ya, Tol::Abs(1e-5), &what("inference output"));
        }
    }
}
