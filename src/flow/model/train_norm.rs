//! Instance and group normalisation of training (the encoders of Note S10) as one autodiff
//! operation on the CPU backend, forward and backward on host memory
//! ([`super::host_norm::normalise`], [`super::host_norm::normalise_backward`]): two passes each
//! way over every group, where burn's layer is a chain of eight whole-tensor operations and
//! their gradients. Other devices, other dtypes and layers without affine parameters keep
//! burn's layer.

use burn::backend::Flex;
use burn::backend::autodiff::NodeId;
use burn::backend::autodiff::checkpoint::base::Checkpointer;
use burn::backend::autodiff::checkpoint::strategy::NoCheckpointing;
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, Ops, OpsKind};
use burn::prelude::*;

use super::flex_bridge::{Ad, AdT, HostView, from_host};
use super::host_norm::{normalise, normalise_backward};

/// Group normalisation with affine parameters under autodiff on the CPU backend; `None` when
/// the tensors are elsewhere (the caller then uses burn's layer).
///
/// # Shapes
/// `x` `[B, C, H, W]`, `gamma`, `beta` `[C]` → `[B, C, H, W]`
pub fn group_norm_train(
    x: &Tensor<4>,
    groups: usize,
    epsilon: f64,
    gamma: &Tensor<1>,
    beta: &Tensor<1>,
) -> Option<Tensor<4>> {
    let [_, c, _, _] = x.dims();
    if groups == 0 || c % groups != 0 || gamma.dims() != [c] || beta.dims() != [c] {
        return None;
    }
    let f32s = [x.dtype(), gamma.dtype(), beta.dtype()]
        .iter()
        .all(|d| *d == burn::tensor::DType::F32);
    if !f32s {
        return None;
    }
    let xp = x.clone().try_into_primitive::<Ad>().ok()?;
    let gp = gamma.clone().try_into_primitive::<Ad>().ok()?;
    let bp = beta.clone().try_into_primitive::<Ad>().ok()?;
    Some(Tensor::from_primitive::<Ad>(norm_op(
        xp, gp, bp, groups, epsilon,
    )))
}

fn norm_op(x: AdT, gamma: AdT, beta: AdT, groups: usize, epsilon: f64) -> AdT {
    #[derive(Debug)]
    struct HostNorm;

    impl Backward<Flex, 3> for HostNorm {
        type State = (NodeId, NodeId, usize, f64);

        fn backward(
            self,
            ops: Ops<Self::State, 3>,
            grads: &mut Gradients,
            checkpointer: &mut Checkpointer,
        ) {
            let [node_x, node_g, node_b] = ops.parents;
            let dy = HostView::<4>::new(grads.consume::<Flex>(&ops.node));
            let [b, c, h, w] = dy.dims;
            let (x_state, g_state, groups, epsilon) = ops.state;
            let x = HostView::<4>::new(checkpointer.retrieve_node_output(x_state));
            let gamma = HostView::<1>::new(checkpointer.retrieve_node_output(g_state));
            let (dx, dg, db) = normalise_backward(
                x.values(),
                dy.values(),
                [b, c, h * w],
                groups,
                epsilon,
                gamma.values(),
            );
            if let Some(node) = node_x {
                grads.register::<Flex>(node.id, from_host(dx, [b, c, h, w]));
            }
            if let Some(node) = node_g {
                grads.register::<Flex>(node.id, from_host(dg, [c]));
            }
            if let Some(node) = node_b {
                grads.register::<Flex>(node.id, from_host(db, [c]));
            }
        }
    }

    let forward = |x: &AdT, gamma: &AdT, beta: &AdT| {
        let xv = HostView::<4>::new(x.primitive().clone());
        let [b, c, h, w] = xv.dims;
        let g = HostView::<1>::new(gamma.primitive().clone());
        let bt = HostView::<1>::new(beta.primitive().clone());
        let y = normalise(
            xv.values(),
            [b, c, h * w],
            groups,
            epsilon,
            Some((g.values(), bt.values())),
        );
        from_host(y, [b, c, h, w])
    };
    match HostNorm
        .prepare::<NoCheckpointing>([x.node(), gamma.node(), beta.node()])
        .compute_bound()
        .stateful()
    {
        OpsKind::Tracked(mut prep) => {
            let x_state = prep.checkpoint(&x);
            let g_state = prep.checkpoint(&gamma);
            let y = forward(&x, &gamma, &beta);
            prep.finish((x_state, g_state, groups, epsilon), y)
        }
        OpsKind::UnTracked(prep) => prep.finish(forward(&x, &gamma, &beta)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::nn::{GroupNormConfig, InstanceNormConfig};
    use burn::tensor::Distribution;

    /// Output and the gradients of input, γ and β equal burn's layers, for instance
    /// normalisation and groups of several channels, under a loss that weights every output
    /// differently.
    #[test]
    fn host_training_norm_matches_burn() {
        let dev = Device::flex().autodiff();
        for groups in [12, 4] {
            let x0 = Tensor::<4>::random([2, 12, 5, 7], Distribution::Normal(2.0, 3.0), &dev);
            let g0 = Tensor::<1>::random([12], Distribution::Normal(1.0, 0.5), &dev);
            let b0 = Tensor::<1>::random([12], Distribution::Normal(0.0, 0.5), &dev);
            let weights = Tensor::<4>::random([2, 12, 5, 7], Distribution::Normal(0.0, 1.0), &dev);
            let run = |host: bool| {
                let x = x0.clone().detach().require_grad();
                let (g, b) = (
                    g0.clone().detach().require_grad(),
                    b0.clone().detach().require_grad(),
                );
                let y = if host {
                    group_norm_train(&x, groups, 1e-5, &g, &b).expect("host path")
                } else if groups == 12 {
                    let mut n = InstanceNormConfig::new(12).init(&dev);
                    n.gamma = Some(burn::module::Param::from_tensor(g.clone()));
                    n.beta = Some(burn::module::Param::from_tensor(b.clone()));
                    n.forward(x.clone())
                } else {
                    let mut n = GroupNormConfig::new(groups, 12).init(&dev);
                    n.gamma = Some(burn::module::Param::from_tensor(g.clone()));
                    n.beta = Some(burn::module::Param::from_tensor(b.clone()));
                    n.forward(x.clone())
                };
                let grads = (y.clone() * weights.clone()).sum().backward();
                (
                    y.inner(),
                    x.grad(&grads).expect("x gradient"),
                    g.grad(&grads).expect("gamma gradient"),
                    b.grad(&grads).expect("beta gradient"),
                )
            };
            let (ya, xa, ga, ba) = run(true);
            let (yb, xb, gb, bb) = run(false);
            let d4 = |a: Tensor<4>, b: Tensor<4>| -> f32 { (a - b).abs().max().into_scalar() };
            let d1 = |a: Tensor<1>, b: Tensor<1>| -> f32 { (a - b).abs().max().into_scalar() };
            assert!(d4(ya, yb) < 1e-4, "groups {groups}: output");
            assert!(d4(xa, xb) < 1e-4, "groups {groups}: input gradient");
            assert!(d1(ga, gb) < 1e-3, "groups {groups}: gamma gradient");
            assert!(d1(ba, bb) < 1e-3, "groups {groups}: beta gradient");
        }
    }
}
