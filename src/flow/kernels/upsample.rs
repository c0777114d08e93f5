//! Convex upsampling (Note S9) on host values, forward and backward: every full-resolution flow
//! vector is a softmax-weighted convex combination of 8× the flow at the 3×3 coarse neighbours
//! of its 1/8-resolution cell. Per cell and sub-pixel, a softmax over the 9 mask logits and the
//! weighted sum, written straight at full resolution — where the tensor form is a reshape, a
//! softmax, an unfold, a product, a sum and a permutation, each with its own copy and gradient.
//! One task per band of coarse rows, compiled for AVX2/AVX-512 where the CPU has them.
//!
//! Mask channel `k·64 + s` holds neighbour k = 3·ky + kx (offset (ky − 1, kx − 1)) of sub-pixel
//! s = 8·i + j.

use multiversion::multiversion;
use rayon::prelude::*;

use super::vexp::exp;

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
pub fn forward(flow: &[f32], mask: &[f32], [b, h, w]: [usize; 3]) -> Vec<f32> {
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
pub fn backward(
    flow: &[f32],
    mask: &[f32],
    g: &[f32],
    [b, h, w]: [usize; 3],
) -> (Vec<f32>, Vec<f32>) {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flow::kernels::testing::{Tol, assert_close, cases, values};
    use rand::RngExt;

    /// The definition, cell by cell: softmax over the 9 logits of each sub-pixel, then the
    /// weighted sum of 8× the neighbours (zero outside the map).
    fn direct(flow: &[f32], mask: &[f32], [b, h, w]: [usize; 3]) -> Vec<f32> {
        let hw = h * w;
        let mut out = vec![0f32; b * 2 * 64 * hw];
        for bi in 0..b {
            for y in 0..h {
                for x in 0..w {
                    for s in 0..64 {
                        let logits: Vec<f32> = (0..9)
                            .map(|k| mask[(bi * 576 + k * 64 + s) * hw + y * w + x])
                            .collect();
                        let m = logits.iter().fold(f32::MIN, |a, &v| a.max(v));
                        let e: Vec<f32> = logits.iter().map(|v| (v - m).exp()).collect();
                        let total: f32 = e.iter().sum();
                        for d in 0..2 {
                            let mut acc = 0.0;
                            for (k, ek) in e.iter().enumerate() {
                                let (yy, xx) = (
                                    y as isize + (k / 3) as isize - 1,
                                    x as isize + (k % 3) as isize - 1,
                                );
                                if yy >= 0 && xx >= 0 && yy < h as isize && xx < w as isize {
                                    acc += ek / total
                                        * 8.0
                                        * flow[(bi * 2 + d) * hw + yy as usize * w + xx as usize];
                                }
                            }
                            let (i, j) = (s / 8, s % 8);
                            out[((bi * 2 + d) * 8 * h + 8 * y + i) * 8 * w + 8 * x + j] = acc;
                        }
                    }
                }
            }
        }
        out
    }

    /// Property: on random map sizes (seeded, several tasks per image included), the forward
    /// pass is the definition, and the backward pass is its adjoint in the flow (the output is
    /// linear in the flow) and matches central differences in the mask logits.
    #[test]
    fn forward_is_the_definition_and_backward_its_derivative() {
        for case in 0..12 {
            let mut r = cases("convex upsampling", case);
            let (b, h, w) = (
                r.random_range(1..=2),
                r.random_range(1..=5),
                r.random_range(1..=6),
            );
            let hw = h * w;
            let flow = values(&mut r, b * 2 * hw, 2.0);
            let mask = values(&mut r, b * 576 * hw, 3.0);
            let what = format!("case {case}: {b}x{h}x{w}");
            let y = forward(&flow, &mask, [b, h, w]);
            assert_close(&y, &direct(&flow, &mask, [b, h, w]), Tol::Abs(1e-4), &what);
            let g = values(&mut r, y.len(), 1.0);
            let (dflow, dmask) = backward(&flow, &mask, &g, [b, h, w]);
            let dot =
                |a: &[f32], b: &[f32]| a.iter().zip(b).map(|(u, v)| (u * v) as f64).sum::<f64>();
            let (lhs, rhs) = (dot(&y, &g), dot(&flow, &dflow));
            let scale = (lhs.abs() + 1.0) as f32;
            assert_close(
                &[rhs as f32 / scale],
                &[lhs as f32 / scale],
                Tol::Abs(1e-4),
                &format!("flow adjoint, {what}"),
            );
            // A few mask logits by central differences.
            for _ in 0..8 {
                let i = r.random_range(0..mask.len());
                let eps = 1e-2f32;
                let (mut up, mut down) = (mask.clone(), mask.clone());
                up[i] += eps;
                down[i] -= eps;
                let numeric = (dot(&forward(&flow, &up, [b, h, w]), &g)
                    - dot(&forward(&flow, &down, [b, h, w]), &g))
                    / (2.0 * eps as f64);
                assert_close(
                    &[dmask[i]],
                    &[numeric as f32],
                    Tol::Scaled(2e-2),
                    &format!("∂L/∂mask[{i}], {what}"),
                );
            }
        }
    }
}
