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
use multiversion::multiversion;
use rayon::prelude::*;

use super::flex_bridge::{Ad, AdT, HostView, from_host};
use super::vexp::exp;

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

/// Cells per task (whole coarse rows, at least two tasks per image).
const CELLS_PER_TASK: usize = 512;

/// The tasks: (image, first coarse row, end row), each owning full-resolution rows
/// `8·y0 .. 8·y1` of its image.
fn tasks(b: usize, h: usize, w: usize) -> Vec<(usize, usize, usize)> {
    let rows = (CELLS_PER_TASK / w.max(1)).clamp(1, h.div_ceil(2).max(1));
    (0..b)
        .flat_map(|bi| {
            (0..h)
                .step_by(rows)
                .map(move |y0| (bi, y0, (y0 + rows).min(h)))
        })
        .collect()
}

/// The softmax over the 9 neighbours of the cells `[p0, p0 + n)` of one image, for all 64
/// sub-pixels: `wk[(k·64 + s)·n + c]`, from its logits `mask` `[576, H·W]`. Each step is a loop
/// over `64·n` contiguous values.
#[inline(always)] // into the SIMD versions of the tasks
fn softmax_weights(mask: &[f32], hw: usize, p0: usize, n: usize, wk: &mut [f32]) {
    for (ch, dst) in wk.chunks_exact_mut(n).enumerate() {
        dst.copy_from_slice(&mask[ch * hw + p0..][..n]);
    }
    let m = 64 * n;
    let mut max = wk[..m].to_vec();
    for k in 1..9 {
        for (mx, &v) in max.iter_mut().zip(&wk[k * m..(k + 1) * m]) {
            *mx = mx.max(v);
        }
    }
    let mut sum = vec![0f32; m];
    for plane in wk.chunks_exact_mut(m) {
        for ((e, &mx), t) in plane.iter_mut().zip(&max).zip(&mut sum) {
            *e = exp(*e - mx);
            *t += *e;
        }
    }
    for plane in wk.chunks_exact_mut(m) {
        for (e, &t) in plane.iter_mut().zip(&sum) {
            *e /= t;
        }
    }
}

/// 8× the flow at the 9 neighbours of the cells of coarse rows `[y0, y1)`, zero outside the
/// map: `nb[(d·9 + k)·n + c]` for neighbour k = 3·ky + kx at offset (ky − 1, kx − 1).
fn neighbours(flow: &[f32], [h, w]: [usize; 2], y0: usize, y1: usize) -> Vec<f32> {
    let n = (y1 - y0) * w;
    let mut nb = vec![0f32; 18 * n];
    for d in 0..2 {
        for k in 0..9 {
            let (dy, dx) = ((k / 3) as isize - 1, (k % 3) as isize - 1);
            for y in y0..y1 {
                let yy = y as isize + dy;
                if yy < 0 || yy >= h as isize {
                    continue;
                }
                let src = &flow[d * h * w + yy as usize * w..][..w];
                let dst = &mut nb[(d * 9 + k) * n + (y - y0) * w..][..w];
                // Columns x whose neighbour x + dx lies inside [0, W).
                let lo = (-dx).max(0) as usize;
                let hi = (w as isize - dx.max(0)).max(0) as usize;
                for x in lo..hi.max(lo) {
                    dst[x] = 8.0 * src[(x as isize + dx) as usize];
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
    let tasks = tasks(b, h, w);
    let slabs: Vec<Vec<f32>> = tasks
        .par_iter()
        .map(|&(bi, y0, y1)| forward_task(flow, mask, [h, w], bi, y0, y1))
        .collect();
    for (&(bi, y0, y1), slab) in tasks.iter().zip(slabs) {
        let len = (y1 - y0) * 64 * w;
        for d in 0..2 {
            let at = ((bi * 2 + d) * 8 * h + 8 * y0) * wf;
            out[at..at + len].copy_from_slice(&slab[d * len..(d + 1) * len]);
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
    let hw = h * w;
    let tasks = tasks(b, h, w);
    // Per task: ∂L/∂mask [576, n] and coef [18, n], coef[d, k, c] = 8 Σ_s w_k(c, s) g_d(c, s),
    // what neighbour k of cell c receives.
    let per_task: Vec<(Vec<f32>, Vec<f32>)> = tasks
        .par_iter()
        .map(|&(bi, y0, y1)| backward_task(flow, mask, g, [h, w], bi, y0, y1))
        .collect();
    let mut dmask = vec![0f32; b * 576 * hw];
    let mut coef = vec![0f32; b * 18 * hw];
    for (&(bi, y0, y1), (dm, cf)) in tasks.iter().zip(per_task) {
        let n = (y1 - y0) * w;
        for (ch, src) in dm.chunks_exact(n).enumerate() {
            dmask[(bi * 576 + ch) * hw + y0 * w..][..n].copy_from_slice(src);
        }
        for (dk, src) in cf.chunks_exact(n).enumerate() {
            coef[(bi * 18 + dk) * hw + y0 * w..][..n].copy_from_slice(src);
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

/// Full-resolution rows `8·y0 .. 8·y1` of image `bi`, both channels: `[2, 8·(y1 − y0), 8W]`.
#[multiversion(targets = "simd")]
fn forward_task(
    flow: &[f32],
    mask: &[f32],
    [h, w]: [usize; 2],
    bi: usize,
    y0: usize,
    y1: usize,
) -> Vec<f32> {
    let (hw, wf) = (h * w, 8 * w);
    let n = (y1 - y0) * w;
    let nb = neighbours(&flow[bi * 2 * hw..(bi + 1) * 2 * hw], [h, w], y0, y1);
    let mut wk = vec![0f32; 576 * n];
    softmax_weights(&mask[bi * 576 * hw..], hw, y0 * w, n, &mut wk);
    // Full-resolution rows 8·y0 .. 8·y1 of both channels.
    let mut slab = vec![0f32; 2 * 64 * n];
    let mut acc = vec![0f32; 64 * n];
    for d in 0..2 {
        acc.fill(0.0);
        for k in 0..9 {
            let nbk = &nb[(d * 9 + k) * n..][..n];
            for (a, wks) in acc
                .chunks_exact_mut(n)
                .zip(wk[k * 64 * n..].chunks_exact(n))
            {
                for ((a, &wv), &v) in a.iter_mut().zip(wks).zip(nbk) {
                    *a += wv * v;
                }
            }
        }
        // acc[s][c] → row 8·y + i, column 8·x + j, for s = 8·i + j and c = (y − y0)·W + x.
        let dst = &mut slab[d * 64 * n..(d + 1) * 64 * n];
        for (s, a) in acc.chunks_exact(n).enumerate() {
            let (i, j) = (s / 8, s % 8);
            for (yl, row) in a.chunks_exact(w).enumerate() {
                let line = &mut dst[(8 * yl + i) * wf..][..wf];
                for (x, &v) in row.iter().enumerate() {
                    line[8 * x + j] = v;
                }
            }
        }
    }
    slab
}

/// ∂L/∂mask `[576, n]` and coef `[18, n]` of the cells of coarse rows `[y0, y1)` of image `bi`.
#[multiversion(targets = "simd")]
fn backward_task(
    flow: &[f32],
    mask: &[f32],
    g: &[f32],
    [h, w]: [usize; 2],
    bi: usize,
    y0: usize,
    y1: usize,
) -> (Vec<f32>, Vec<f32>) {
    let (hw, wf) = (h * w, 8 * w);
    let n = (y1 - y0) * w;
    let nb = neighbours(&flow[bi * 2 * hw..(bi + 1) * 2 * hw], [h, w], y0, y1);
    let mut wk = vec![0f32; 576 * n];
    softmax_weights(&mask[bi * 576 * hw..], hw, y0 * w, n, &mut wk);
    // gs[d][s][c]: the output gradient at sub-pixel s of cell c.
    let mut gs = vec![0f32; 2 * 64 * n];
    for d in 0..2 {
        for yl in 0..y1 - y0 {
            for i in 0..8 {
                let src = &g[((bi * 2 + d) * 8 * h + 8 * (y0 + yl) + i) * wf..][..wf];
                for j in 0..8 {
                    let dst = &mut gs[(d * 64 + 8 * i + j) * n + yl * w..][..w];
                    for (x, v) in dst.iter_mut().enumerate() {
                        *v = src[8 * x + j];
                    }
                }
            }
        }
    }
    let mut dm = vec![0f32; 576 * n];
    let mut cf = vec![0f32; 18 * n];
    let (mut t, mut wt) = (vec![0f32; 9 * n], vec![0f32; n]);
    for s in 0..64 {
        let (g0, g1) = (&gs[s * n..][..n], &gs[(64 + s) * n..][..n]);
        // t_k = ∂L/∂w_k; softmax: ∂L/∂l_k = w_k (t_k − Σ w t).
        wt.fill(0.0);
        for k in 0..9 {
            let wks = &wk[(k * 64 + s) * n..][..n];
            let (n0, n1) = (&nb[k * n..][..n], &nb[(9 + k) * n..][..n]);
            let tk = &mut t[k * n..][..n];
            for c in 0..n {
                tk[c] = g0[c] * n0[c] + g1[c] * n1[c];
                wt[c] += wks[c] * tk[c];
            }
        }
        for k in 0..9 {
            let wks = &wk[(k * 64 + s) * n..][..n];
            let dst = &mut dm[(k * 64 + s) * n..][..n];
            let (c0, c1) = cf.split_at_mut(9 * n);
            let (c0, c1) = (&mut c0[k * n..][..n], &mut c1[k * n..][..n]);
            for c in 0..n {
                dst[c] = wks[c] * (t[k * n + c] - wt[c]);
                c0[c] += 8.0 * wks[c] * g0[c];
                c1[c] += 8.0 * wks[c] * g1[c];
            }
        }
    }
    (dm, cf)
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
