//! One level's correlation lookup in training on the CPU as one tracked operation, and its
//! `Backward`: the window's gradient added back onto the level by
//! [`crate::flow::kernels::lookup::Window::backward`]. The positions carry no gradient, as in
//! RAFT.

use burn::backend::Flex;
use burn::backend::autodiff::checkpoint::base::Checkpointer;
use burn::backend::autodiff::checkpoint::strategy::NoCheckpointing;
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, Ops, OpsKind};
use burn::prelude::*;

use super::bridge::{Ad, AdT, HostView, from_host};
use crate::flow::kernels::lookup::Window;

/// The window lookup of level `l` as a tracked operation; `None` when the shapes do not fit or
/// the level is not an f32 tensor of the autodiff CPU backend (the caller then uses the tensor
/// form).
///
/// # Shapes
/// `level` `[B·H·W, hl, wl]`, `coords` `[B, 2, H, W]` → `[B, (2r+1)², H, W]`
pub fn tracked(
    level: &Tensor<3>,
    coords: &Tensor<4>,
    radius: usize,
    l: usize,
) -> Option<Tensor<4>> {
    let [b, two, h, w] = coords.dims();
    let [n, hl, wl] = level.dims();
    if two != 2 || n != b * h * w || level.dtype() != burn::tensor::DType::F32 {
        return None;
    }
    let lp = level.clone().try_into_primitive::<Ad>().ok()?;
    let plain = if coords.is_autodiff() {
        coords.clone().inner()
    } else {
        coords.clone()
    };
    let c = plain.into_data().try_into_vec::<f32>().ok()?;
    let win = Window {
        b,
        h,
        w,
        hl,
        wl,
        r: radius,
        scale: 1.0 / (1u64 << l) as f32,
    };
    Some(Tensor::from_primitive::<Ad>(op(lp, c, win)))
}

#[derive(Debug)]
struct HostLookup;

impl Backward<Flex, 1> for HostLookup {
    type State = (Vec<f32>, Window);

    fn backward(self, ops: Ops<Self::State, 1>, grads: &mut Gradients, _: &mut Checkpointer) {
        let [node] = ops.parents;
        let gv = HostView::<4>::new(grads.consume::<Flex>(&ops.node));
        let (coords, win) = ops.state;
        if let Some(node) = node {
            let d = win.backward(&coords, gv.values());
            let shape = [win.b * win.h * win.w, win.hl, win.wl];
            grads.register::<Flex>(node.id, from_host(d, shape));
        }
    }
}

fn op(level: AdT, coords: Vec<f32>, win: Window) -> AdT {
    let run = |level: &AdT| {
        let v = HostView::<3>::new(level.primitive().clone());
        let k = win.k();
        from_host(
            win.forward(v.values(), &coords),
            [win.b, k * k, win.h, win.w],
        )
    };
    match HostLookup
        .prepare::<NoCheckpointing>([level.node()])
        .compute_bound()
        .stateful()
    {
        OpsKind::Tracked(prep) => {
            let y = run(&level);
            prep.finish((coords, win), y)
        }
        OpsKind::UnTracked(prep) => prep.finish(run(&level)),
    }
}
