//! Convex upsampling (Note S9) on host memory for the CPU backend, forward and backward, used at
//! inference directly and in training as one autodiff operation: per cell and sub-pixel, a
//! softmax over the 9 mask logits and the weighted sum of the 3×3 coarse neighbours (×8), written
//! straight at full resolution — where the tensor form is a reshape, a softmax, an unfold, a
//! product, a sum and a permutation, each with its own copy and gradient.
//!
//! Mask channel `k·64 + s` holds neighbour k = 3·ky + kx (offset (ky − 1, kx − 1)) of sub-pixel
//! s = 8·i + j, as [`super::upsample::convex_upsample`] reads it.

use burn::backend::Flex;
use burn::backend::autodiff::NodeId;
use burn::backend::autodiff::checkpoint::base::Checkpointer;
use burn::backend::autodiff::checkpoint::strategy::NoCheckpointing;
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, Ops, OpsKind};
use burn::prelude::*;
use rayon::prelude::*;

use super::flex_bridge::{Ad, AdT, HostView, from_host};

/// The convex upsampling on the CPU backend (with or without autodiff); `None` elsewhere or for
/// other dtypes (the caller then uses the tensor form).
///
/// # Shapes
/// `flow` `[B, 2, H, W]`, `mask` `[B, 576, H, W]` → `[B, 2, 8H, 8W]`
pub fn convex_upsample_host(flow: &Tensor<4>, mask: &Tensor<4>) -> Option<Tensor<4>> {
    let f32s = flow.dtype() == burn::tensor::DType::F32 && mask.dtype() == burn::tensor::DType::F32;
    let [b, c, h, w] = flow.dims();
    if !f32s || c != 2 || mask.dims() != [b, 576, h, w] {
        return None;
    }
    if flow.is_autodiff() || mask.is_autodiff() {
        let fp = flow.clone().try_into_primitive::<Ad>().ok()?;
        let mp = mask.clone().try_into_primitive::<Ad>().ok()?;
        return Some(Tensor::from_primitive::<Ad>(upsample_op(fp, mp)));
    }
    if flow.device() != Device::flex() {
        return None;
    }
    let fv = flow.clone().into_data().try_into_vec::<f32>().ok()?;
    let mv = mask.clone().into_data().try_into_vec::<f32>().ok()?;
    let out = forward(&fv, &mv, [b, h, w]);
    Some(Tensor::from_data(
        TensorData::new(out, [b, 2, 8 * h, 8 * w]),
        &flow.device(),
    ))
}

/// The softmax weights of sub-pixel `s` for the cells of one coarse row: `wk[k·w + x]` over the
/// 9 neighbours k, from the logits at channels `k·64 + s` (contiguous along the row).
fn row_weights(mask: &[f32], hw: usize, s: usize, row: usize, w: usize, wk: &mut [f32]) {
    let mut max = vec![f32::NEG_INFINITY; w];
    for k in 0..9 {
        let l = &mask[(k * 64 + s) * hw + row..][..w];
        for (m, &v) in max.iter_mut().zip(l) {
            *m = m.max(v);
        }
    }
    let mut sum = vec![0f32; w];
    for k in 0..9 {
        let l = &mask[(k * 64 + s) * hw + row..][..w];
        for (((e, &v), m), t) in wk[k * w..(k + 1) * w]
            .iter_mut()
            .zip(l)
            .zip(&max)
            .zip(&mut sum)
        {
            *e = (v - m).exp();
            *t += *e;
        }
    }
    for k in 0..9 {
        for (e, t) in wk[k * w..(k + 1) * w].iter_mut().zip(&sum) {
            *e /= t;
        }
    }
}

/// 8× the flow at the 9 neighbours of every cell of coarse row y, zero outside the map:
/// `nb[(d·9 + k)·w + x]`.
fn row_neighbours(flow: &[f32], [h, w]: [usize; 2], y: usize) -> Vec<f32> {
    let mut nb = vec![0f32; 18 * w];
    for d in 0..2 {
        for k in 0..9 {
            let yy = y as isize + (k / 3) as isize - 1;
            if yy < 0 || yy >= h as isize {
                continue;
            }
            let src = &flow[d * h * w + yy as usize * w..][..w];
            let dst = &mut nb[(d * 9 + k) * w..(d * 9 + k + 1) * w];
            // Neighbour column x + kx − 1.
            for (x, v) in dst.iter_mut().enumerate() {
                let xx = x as isize + (k % 3) as isize - 1;
                if xx >= 0 && xx < w as isize {
                    *v = 8.0 * src[xx as usize];
                }
            }
        }
    }
    nb
}

/// # Shapes
/// `flow` `[B, 2, H, W]`, `mask` `[B, 576, H, W]` → `[B, 2, 8H, 8W]`
fn forward(flow: &[f32], mask: &[f32], [b, h, w]: [usize; 3]) -> Vec<f32> {
    let (hw, wf) = (h * w, 8 * w);
    let mut out = vec![0f32; b * 2 * 64 * hw];
    // One task per image and coarse row: it owns full-resolution rows 8y..8y+8 of both channels.
    let rows: Vec<(usize, usize)> = (0..b).flat_map(|bi| (0..h).map(move |y| (bi, y))).collect();
    let chunks: Vec<Vec<f32>> = rows
        .par_iter()
        .map(|&(bi, y)| {
            let (f, m) = (
                &flow[bi * 2 * hw..(bi + 1) * 2 * hw],
                &mask[bi * 576 * hw..(bi + 1) * 576 * hw],
            );
            let nb = row_neighbours(f, [h, w], y);
            let mut wk = vec![0f32; 9 * w];
            let mut rowbuf = vec![0f32; 2 * 8 * wf];
            for s in 0..64 {
                row_weights(m, hw, s, y * w, w, &mut wk);
                let (i, j) = (s / 8, s % 8);
                for d in 0..2 {
                    let dst = &mut rowbuf[(d * 8 + i) * wf..(d * 8 + i + 1) * wf];
                    for x in 0..w {
                        dst[8 * x + j] = (0..9)
                            .map(|k| wk[k * w + x] * nb[(d * 9 + k) * w + x])
                            .sum();
                    }
                }
            }
            rowbuf
        })
        .collect();
    for ((bi, y), rowbuf) in rows.into_iter().zip(chunks) {
        for d in 0..2 {
            for i in 0..8 {
                let dst = ((bi * 2 + d) * 8 * h + 8 * y + i) * wf;
                out[dst..dst + wf].copy_from_slice(&rowbuf[(d * 8 + i) * wf..(d * 8 + i + 1) * wf]);
            }
        }
    }
    out
}

/// Gradients of [`forward`] with respect to the flow and the mask logits, given the gradient
/// `g` `[B, 2, 8H, 8W]` of the output.
///
/// # Shapes
/// → (`[B, 2, H, W]`, `[B, 576, H, W]`)
fn backward(flow: &[f32], mask: &[f32], g: &[f32], [b, h, w]: [usize; 3]) -> (Vec<f32>, Vec<f32>) {
    let (hw, wf) = (h * w, 8 * w);
    let mut dmask = vec![0f32; b * 576 * hw];
    // coef[b, d, k, p] = 8 Σ_s w_k(p, s) g_d(p, s): what neighbour k of cell p receives.
    let mut coef = vec![0f32; b * 2 * 9 * hw];
    // One task per image and coarse row: ∂L/∂mask `[576, w]` and coef `[18, w]` of its cells.
    let rows: Vec<(usize, usize)> = (0..b).flat_map(|bi| (0..h).map(move |y| (bi, y))).collect();
    let per_row: Vec<(Vec<f32>, Vec<f32>)> = rows
        .par_iter()
        .map(|&(bi, y)| {
            let (f, m) = (
                &flow[bi * 2 * hw..(bi + 1) * 2 * hw],
                &mask[bi * 576 * hw..(bi + 1) * 576 * hw],
            );
            let nb = row_neighbours(f, [h, w], y);
            let mut wk = vec![0f32; 9 * w];
            let mut dm = vec![0f32; 576 * w];
            let mut cf = vec![0f32; 18 * w];
            let (mut gd, mut t, mut wt) = (vec![0f32; 2 * w], vec![0f32; 9 * w], vec![0f32; w]);
            for s in 0..64 {
                row_weights(m, hw, s, y * w, w, &mut wk);
                let (i, j) = (s / 8, s % 8);
                for d in 0..2 {
                    let src = &g[((bi * 2 + d) * 8 * h + 8 * y + i) * wf..][..wf];
                    for (x, v) in gd[d * w..(d + 1) * w].iter_mut().enumerate() {
                        *v = src[8 * x + j];
                    }
                }
                // t_k = ∂L/∂w_k; softmax: ∂L/∂l_k = w_k (t_k − Σ w t).
                wt.fill(0.0);
                for k in 0..9 {
                    for x in 0..w {
                        let tk = gd[x] * nb[k * w + x] + gd[w + x] * nb[(9 + k) * w + x];
                        t[k * w + x] = tk;
                        wt[x] += wk[k * w + x] * tk;
                    }
                }
                for k in 0..9 {
                    let dst = &mut dm[(k * 64 + s) * w..(k * 64 + s + 1) * w];
                    for x in 0..w {
                        let wx = wk[k * w + x];
                        dst[x] = wx * (t[k * w + x] - wt[x]);
                        cf[k * w + x] += 8.0 * wx * gd[x];
                        cf[(9 + k) * w + x] += 8.0 * wx * gd[w + x];
                    }
                }
            }
            (dm, cf)
        })
        .collect();
    for ((bi, y), (dm, cf)) in rows.into_iter().zip(per_row) {
        for (ch, src) in dm.chunks_exact(w).enumerate() {
            dmask[(bi * 576 + ch) * hw + y * w..][..w].copy_from_slice(src);
        }
        for (dk, src) in cf.chunks_exact(w).enumerate() {
            coef[(bi * 18 + dk) * hw + y * w..][..w].copy_from_slice(src);
        }
    }
    // ∂L/∂flow(q) = Σ_k coef_k(q − offset_k): gathered, so every cell is written once.
    let mut dflow = vec![0f32; b * 2 * hw];
    dflow
        .par_chunks_mut(hw.max(1))
        .enumerate()
        .for_each(|(bd, dst)| {
            let src = &coef[bd * 9 * hw..(bd + 1) * 9 * hw];
            for (q, v) in dst.iter_mut().enumerate() {
                let (qy, qx) = ((q / w) as isize, (q % w) as isize);
                let mut acc = 0.0;
                for k in 0..9 {
                    let (py, px) = (qy - (k / 3) as isize + 1, qx - (k % 3) as isize + 1);
                    if py >= 0 && px >= 0 && py < h as isize && px < w as isize {
                        acc += src[k * hw + py as usize * w + px as usize];
                    }
                }
                *v = acc;
            }
        });
    (dflow, dmask)
}

fn upsample_op(flow: AdT, mask: AdT) -> AdT {
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
    use super::super::upsample::convex_upsample_tensor;
    use super::*;
    use burn::tensor::Distribution;

    /// Output and both gradients equal the tensor form's, borders included, and the plain
    /// (inference) form gives the same output.
    #[test]
    fn host_upsampling_matches_the_tensor_form() {
        let dev = Device::flex().autodiff();
        let (b, h, w) = (2, 3, 5);
        let f0 = Tensor::<4>::random([b, 2, h, w], Distribution::Normal(0.0, 2.0), &dev);
        let m0 = Tensor::<4>::random([b, 576, h, w], Distribution::Normal(0.0, 3.0), &dev);
        let weights =
            Tensor::<4>::random([b, 2, 8 * h, 8 * w], Distribution::Normal(0.0, 1.0), &dev);
        let run = |host: bool| {
            let (f, m) = (
                f0.clone().detach().require_grad(),
                m0.clone().detach().require_grad(),
            );
            let y = if host {
                convex_upsample_host(&f, &m).expect("host path")
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
        let d = |a: Tensor<4>, b: Tensor<4>| -> f32 { (a - b).abs().max().into_scalar() };
        assert!(d(ya.clone(), yb) < 1e-4, "output");
        assert!(d(fa, fb) < 1e-3, "flow gradient");
        assert!(d(ma, mb) < 1e-4, "mask gradient");
        let plain = convex_upsample_host(&f0.inner(), &m0.inner()).expect("inference path");
        assert!(d(plain, ya) < 1e-5, "inference output");
    }
}
