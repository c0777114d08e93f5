//! Instance and group normalisation (the encoders of Note S10) as one operation: the numbers of
//! `burn::nn::{InstanceNorm, GroupNorm}`, on the host kernel ([`crate::flow::kernels::norm`]) for
//! plain CPU tensors, as one tracked operation with its `Backward` in training on the CPU
//! (layers with affine parameters), and as Burn's layer elsewhere.

use burn::backend::Flex;
use burn::backend::autodiff::NodeId;
use burn::backend::autodiff::checkpoint::base::Checkpointer;
use burn::backend::autodiff::checkpoint::strategy::NoCheckpointing;
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, Ops, OpsKind};
use burn::module::Param;
use burn::nn::{GroupNorm, InstanceNorm};
use burn::prelude::*;

use super::bridge::{Ad, AdT, HostView, from_host};
use super::route::{Operand, Route};
use crate::flow::kernels::norm::{normalise, normalise_backward};

/// A normalisation layer of the network.
#[derive(Clone, Copy, Debug)]
pub enum NormLayer<'a> {
    /// Per image and channel.
    Instance(&'a InstanceNorm),
    /// Per image and group of channels.
    Group(&'a GroupNorm),
}

/// `layer.forward(x)`, on the route of `x` and the layer's parameters.
///
/// # Shapes
/// `[B, C, H, W]` → `[B, C, H, W]`
pub fn norm(layer: NormLayer<'_>, x: Tensor<4>) -> Tensor<4> {
    let val = |p: &Option<Param<Tensor<1>>>| p.as_ref().map(|p| p.val());
    let (groups, epsilon, gamma, beta) = match layer {
        NormLayer::Instance(n) => (n.num_channels, n.epsilon, val(&n.gamma), val(&n.beta)),
        NormLayer::Group(n) => (n.num_groups, n.epsilon, val(&n.gamma), val(&n.beta)),
    };
    let route = Route::of(
        std::iter::once(Operand::of(&x)).chain(gamma.iter().chain(&beta).map(Operand::of)),
    );
    let divides = groups > 0 && x.dims()[1].is_multiple_of(groups);
    let y = match (route, &gamma, &beta) {
        (Route::HostAutodiff, Some(g), Some(b)) if divides => tracked(&x, groups, epsilon, g, b),
        (Route::Host, _, _) if divides => host(&x, groups, epsilon, gamma.as_ref(), beta.as_ref()),
        _ => None,
    };
    y.unwrap_or_else(|| match layer {
        NormLayer::Instance(n) => n.forward(x),
        NormLayer::Group(n) => n.forward(x),
    })
}

/// The normalisation on the host kernel, with the affine parameters when both are given.
fn host(
    x: &Tensor<4>,
    groups: usize,
    epsilon: f64,
    gamma: Option<&Tensor<1>>,
    beta: Option<&Tensor<1>>,
) -> Option<Tensor<4>> {
    let [b, c, h, w] = x.dims();
    let xv = HostView::of(x.clone())?;
    let affine = match (gamma, beta) {
        (Some(g), Some(bt)) => Some((HostView::of(g.clone())?, HostView::of(bt.clone())?)),
        _ => None,
    };
    let affine = affine.as_ref().map(|(g, bt)| (g.values(), bt.values()));
    let out = normalise(xv.values(), [b, c, h * w], groups, epsilon, affine);
    Some(Tensor::from_data(
        TensorData::new(out, [b, c, h, w]),
        &x.device(),
    ))
}

/// The normalisation with affine parameters as one tracked operation; `None` when the shapes
/// do not fit or an operand is not on the autodiff CPU backend.
fn tracked(
    x: &Tensor<4>,
    groups: usize,
    epsilon: f64,
    gamma: &Tensor<1>,
    beta: &Tensor<1>,
) -> Option<Tensor<4>> {
    let [_, c, _, _] = x.dims();
    if gamma.dims() != [c] || beta.dims() != [c] {
        return None;
    }
    let xp = x.clone().try_into_primitive::<Ad>().ok()?;
    let gp = gamma.clone().try_into_primitive::<Ad>().ok()?;
    let bp = beta.clone().try_into_primitive::<Ad>().ok()?;
    Some(Tensor::from_primitive::<Ad>(op(
        xp, gp, bp, groups, epsilon,
    )))
}

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

fn op(x: AdT, gamma: AdT, beta: AdT, groups: usize, epsilon: f64) -> AdT {
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
    use crate::flow::kernels::testing::{Tol, cases};
    use crate::flow::ops::testing::{assert_tensors_close, random};
    use burn::nn::{GroupNormConfig, InstanceNormConfig};
    use burn::tensor::Distribution;
    use rand::RngExt;

    /// Instance and group normalisation match Burn's layers, with trained-looking affine
    /// parameters, on an offset, badly scaled input; a constant map normalises to the shift.
    #[test]
    fn host_norms_match_burn() {
        let dev = Device::flex();
        let x = Tensor::<4>::random([2, 16, 7, 9], Distribution::Normal(3.0, 5.0), &dev);
        let mut inst = InstanceNormConfig::new(16).init(&dev);
        let mut group = GroupNormConfig::new(8, 16).init(&dev);
        let g = Tensor::<1>::random([16], Distribution::Normal(1.0, 0.5), &dev);
        let bt = Tensor::<1>::random([16], Distribution::Normal(0.0, 0.5), &dev);
        inst.gamma = Some(Param::from_tensor(g.clone()));
        inst.beta = Some(Param::from_tensor(bt.clone()));
        group.gamma = Some(Param::from_tensor(g));
        group.beta = Some(Param::from_tensor(bt));
        let got = norm(NormLayer::Instance(&inst), x.clone());
        assert_tensors_close(got, inst.forward(x.clone()), Tol::Abs(1e-4), "instance");
        let got = norm(NormLayer::Group(&group), x.clone());
        assert_tensors_close(got, group.forward(x), Tol::Abs(1e-4), "group");
        let flat = Tensor::<4>::ones([1, 16, 4, 4], &dev).mul_scalar(7.0);
        let plain = InstanceNormConfig::new(16).with_affine(false).init(&dev);
        let y = norm(NormLayer::Instance(&plain), flat);
        let m: f32 = y.abs().max().into_scalar();
        assert!(m.is_finite() && m < 1e-3, "constant map gave {m}");
    }

    /// Property: random batches, channels, group counts, map sizes, offsets and scales
    /// (seeded) give Burn's layer, with and without affine parameters, at inference, and its
    /// output and the gradients of input, γ and β in training, under a loss that weights every
    /// output differently.
    #[test]
    fn random_norms_match_burn_with_gradients() {
        // Cases 24 and 25 are the former fixed ones: instance normalisation and 4 groups of 3
        // channels on [2, 12, 5, 7], offset 2, with affine parameters.
        for case in 0..26 {
            let mut r = cases("norm vs burn", case);
            let (groups, shape, offset, instance, affine) = if case >= 24 {
                let instance = case == 24;
                (
                    if instance { 12 } else { 4 },
                    [2, 12, 5, 7],
                    2.0,
                    instance,
                    true,
                )
            } else {
                let groups = r.random_range(1..=4);
                let shape = [
                    r.random_range(1..=2),
                    groups * r.random_range(1..=4),
                    r.random_range(1..=9),
                    r.random_range(1..=9),
                ];
                let offset = r.random_range(-3.0f32..3.0);
                (groups, shape, offset, r.random_bool(0.5), case % 3 != 2)
            };
            let c = shape[1];
            for dev in [Device::flex(), Device::flex().autodiff()] {
                let ad = dev.is_autodiff();
                let track = |t: Tensor<1>| if ad { t.require_grad() } else { t };
                let x0 = random(&mut r, shape, 3.0, &dev).add_scalar(offset);
                let weights = random(&mut r, shape, 1.0, &dev);
                let (mut inst, mut group) = (
                    InstanceNormConfig::new(c).with_affine(affine).init(&dev),
                    GroupNormConfig::new(groups, c)
                        .with_affine(affine)
                        .init(&dev),
                );
                if affine {
                    let g = random(&mut r, [c], 0.5, &dev).add_scalar(1.0);
                    let b = random(&mut r, [c], 0.5, &dev);
                    inst.gamma = Some(Param::from_tensor(track(g.clone())));
                    inst.beta = Some(Param::from_tensor(track(b.clone())));
                    group.gamma = Some(Param::from_tensor(track(g)));
                    group.beta = Some(Param::from_tensor(track(b)));
                }
                let layer = if instance {
                    NormLayer::Instance(&inst)
                } else {
                    NormLayer::Group(&group)
                };
                let what = |q: &str| {
                    format!(
                        "case {case} {q}: {shape:?}, instance {instance}, groups {groups}, affine {affine}, autodiff {}",
                        dev.is_autodiff()
                    )
                };
                let x = if ad {
                    x0.clone().require_grad()
                } else {
                    x0.clone()
                };
                let y = norm(layer, x.clone());
                let want = if instance {
                    inst.forward(x0.clone())
                } else {
                    group.forward(x0.clone())
                };
                assert_tensors_close(y.clone(), want.clone(), Tol::Abs(1e-4), &what("output"));
                if !dev.is_autodiff() {
                    continue;
                }
                let xb = x0.clone().require_grad();
                let yb = if instance {
                    inst.forward(xb.clone())
                } else {
                    group.forward(xb.clone())
                };
                let ga = (y * weights.clone()).sum().backward();
                let gb = (yb * weights).sum().backward();
                let (dxa, dxb) = (
                    x.grad(&ga).expect("x gradient"),
                    xb.grad(&gb).expect("x gradient"),
                );
                assert_tensors_close(dxa, dxb, Tol::Abs(1e-4), &what("input gradient"));
                let params = match layer {
                    NormLayer::Instance(n) => (n.gamma.clone(), n.beta.clone()),
                    NormLayer::Group(n) => (n.gamma.clone(), n.beta.clone()),
                };
                if let (Some(g), Some(b)) = params {
                    let (g, b) = (g.val(), b.val());
                    for (t, q) in [(g, "γ gradient"), (b, "β gradient")] {
                        let (a, bb) = (
                            t.grad(&ga).expect("gradient"),
                            t.grad(&gb).expect("gradient"),
                        );
                        assert_tensors_close(a, bb, Tol::Abs(1e-3), &what(q));
                    }
                }
            }
        }
    }
}
