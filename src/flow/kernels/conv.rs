//! The CPU convolution (every layer of Notes S9–S10) on host values: `y = W ⋆ x + b`, the same
//! cross-correlation as `burn::tensor::module::conv2d` (ungrouped), and its three gradients:
//!
//! - forward: by shifted products ([`super::shifted`]) where they are faster, else unfolded
//!   ([`super::unfold`]), one matrix product per band of output rows;
//! - `∂L/∂x = W̃ ⋆ ∂L/∂y`, with `W̃[c, o] = W[o, c]` flipped in both axes and the padding
//!   mirrored (`d·(k−1) − p`): the transposed convolution is a convolution (for stride s, of the
//!   output gradient spread onto the stride-1 grid with zeros between);
//! - `∂L/∂W = Σ ∂L/∂y(band) · cols(band)ᵀ`, the forward unfolding (or shifting) reused;
//! - `∂L/∂b = Σ ∂L/∂y` over images and pixels.

use super::geometry::{ConvParams, Geometry};
use super::{shifted, unfold};

/// The convolution of `x` `[B, Cin, H, W]` by `w` `[Cout, Cin, kh, kw]` (+ `bias` `[Cout]`),
/// returned with its shape `[B, Cout, H', W']`.
pub fn conv2d(
    x: &[f32],
    xs: [usize; 4],
    w: &[f32],
    ws: [usize; 4],
    bias: Option<&[f32]>,
    params: &ConvParams,
) -> (Vec<f32>, [usize; 4]) {
    let g = Geometry::new(xs, ws, params);
    (run(&g, x, w, bias), g.out_shape())
}

/// `∂L/∂W` `[Cout, Cin, kh, kw]` of a convolution, given its input `x` `[B, Cin, H, W]` and the
/// gradient `grad` `[B, Cout, H', W']` of its output: by shifted products where the layer
/// allows them (always faster there), else unfolded.
pub fn weight_grad(
    x: &[f32],
    xs: [usize; 4],
    grad: &[f32],
    [cout, kh, kw]: [usize; 3],
    params: &ConvParams,
) -> Vec<f32> {
    let g = Geometry::new(xs, [cout, xs[1], kh, kw], params);
    let k = g.k();
    if g.ho * g.wo == 0 || k == 0 || cout == 0 {
        return vec![0f32; cout * k];
    }
    if shifted::eligible(&g) {
        return shifted::weight_grad(&g, x, grad);
    }
    unfold::weight_grad(&g, x, grad)
}

/// `∂L/∂x` of a convolution with `params`, from its output gradient `grad` `[B, Cout, H', W']`,
/// its kernel `w` `[Cout, Cin, kh, kw]` and its input size `[H, W]`: the convolution of the
/// (stride-spread) gradient by the flipped, transposed kernel with the padding mirrored. The
/// padding on each side must not exceed the kernel's reach `d·(k − 1)`.
///
/// # Shapes
/// → `[B, Cin, H, W]`
pub fn input_grad(
    grad: &[f32],
    gs: [usize; 4],
    w: &[f32],
    [cout, cin, kh, kw]: [usize; 4],
    [h, w_in]: [usize; 2],
    params: &ConvParams,
) -> (Vec<f32>, [usize; 4]) {
    let [dy, dx] = params.dilation;
    let (py, px) = (dy * (kh - 1), dx * (kw - 1));
    // Input rows and columns past the last window (stride > 1) get zero gradient from extra end
    // padding.
    let [sy, sx] = params.stride;
    let extra =
        |size: usize, (p0, p1): (usize, usize), span: usize, s: usize| (size + p0 + p1 - span) % s;
    let (ey, ex) = (
        extra(h, params.padding[0], py + 1, sy),
        extra(w_in, params.padding[1], px + 1, sx),
    );
    let mirrored = ConvParams {
        stride: [1, 1],
        padding: [
            (py - params.padding[0].0, py - params.padding[0].1 + ey),
            (px - params.padding[1].0, px - params.padding[1].1 + ex),
        ],
        dilation: params.dilation,
    };
    let wt = flip_transpose(w, [cout, cin, kh, kw]);
    let ws = [cin, cout, kh, kw];
    if sy == 1 && sx == 1 {
        conv2d(grad, gs, &wt, ws, None, &mirrored)
    } else {
        let (spread, ss) = stuff(grad, gs, [sy, sx]);
        conv2d(&spread, ss, &wt, ws, None, &mirrored)
    }
}

/// `∂L/∂b` `[Cout]`: the output gradient `grad` `[B, Cout, H', W']` summed over images and
/// pixels.
pub fn bias_grad(grad: &[f32], [_, cout, ho, wo]: [usize; 4]) -> Vec<f32> {
    let mut db = vec![0f32; cout];
    for (i, plane) in grad.chunks_exact((ho * wo).max(1)).enumerate() {
        db[i % cout] += plane.iter().sum::<f32>();
    }
    db
}

/// The forward pass as a row-major `[B, Cout, H', W']`.
fn run(g: &Geometry, x: &[f32], w: &[f32], bias: Option<&[f32]>) -> Vec<f32> {
    let hw_out = g.ho * g.wo;
    if hw_out == 0 || g.cout == 0 {
        return vec![0f32; g.batch * g.cout * hw_out];
    }
    if g.k() == 0 {
        // No input channels: the output is the bias.
        let mut out = vec![0f32; g.batch * g.cout * hw_out];
        if let Some(b) = bias {
            for (c, plane) in out.chunks_exact_mut(hw_out).enumerate() {
                plane.fill(b[c % g.cout]);
            }
        }
        return out;
    }
    if shifted::eligible_forward(g) {
        return shifted::forward(g, x, w, bias);
    }
    unfold::forward(g, x, w, bias)
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flow::kernels::testing::{Tol, assert_close, cases, values};
    use rand::RngExt;

    /// A direct seven-loop convolution, the definition itself.
    fn direct(x: &[f32], xs: [usize; 4], w: &[f32], ws: [usize; 4], p: &ConvParams) -> Vec<f32> {
        let g = Geometry::new(xs, ws, p);
        let mut out = vec![0f32; g.batch * g.cout * g.ho * g.wo];
        for b in 0..g.batch {
            for o in 0..g.cout {
                for oy in 0..g.ho {
                    for ox in 0..g.wo {
                        let mut acc = 0f64;
                        for c in 0..g.cin {
                            for ky in 0..g.kh {
                                for kx in 0..g.kw {
                                    let iy = (oy * g.stride[0] + ky * g.dilation[0]) as isize
                                        - g.pad[0] as isize;
                                    let ix = (ox * g.stride[1] + kx * g.dilation[1]) as isize
                                        - g.pad[1] as isize;
                                    if iy < 0 || ix < 0 || iy >= g.h as isize || ix >= g.w as isize
                                    {
                                        continue;
                                    }
                                    let xv = x
                                        [((b * g.cin + c) * g.h + iy as usize) * g.w + ix as usize];
                                    let wv = w[((o * g.cin + c) * g.kh + ky) * g.kw + kx];
                                    acc += (xv * wv) as f64;
                                }
                            }
                        }
                        out[((b * g.cout + o) * g.ho + oy) * g.wo + ox] = acc as f32;
                    }
                }
            }
        }
        out
    }

    /// Property: on random layers (channels, kernels, strides, dilations, per-side paddings up
    /// to the kernel's reach, map sizes, seeded), the forward pass equals the direct sum, the
    /// input gradient equals the adjoint ⟨W ⋆ x, g⟩ = ⟨x, ∂L/∂x⟩ and the weight gradient the
    /// adjoint ⟨W ⋆ x, g⟩ = ⟨W, ∂L/∂W⟩.
    #[test]
    fn random_layers_match_the_definition_and_its_adjoints() {
        for case in 0..80 {
            let mut r = cases("host conv", case);
            let (kh, kw) = (r.random_range(1..=4) * 2 - 1, r.random_range(1..=4) * 2 - 1);
            let (s, d) = (
                [r.random_range(1..=3), r.random_range(1..=3)],
                r.random_range(1..=3),
            );
            let mut pad = |k: usize| {
                (
                    r.random_range(0..=d * (k - 1)),
                    r.random_range(0..=d * (k - 1)),
                )
            };
            let padding = [pad(kh), pad(kw)];
            let p = ConvParams {
                stride: s,
                padding,
                dilation: [d, d],
            };
            let cin = if r.random_bool(0.3) {
                r.random_range(16..=24)
            } else {
                r.random_range(1..=6)
            };
            let (b, cout) = (r.random_range(1..=2), r.random_range(1..=7));
            let xs = [b, cin, r.random_range(1..=17), r.random_range(1..=19)];
            let ws = [cout, cin, kh, kw];
            let x = values(&mut r, xs.iter().product(), 1.0);
            let w = values(&mut r, ws.iter().product(), 1.0);
            let what = format!("case {case}: x {xs:?}, w {ws:?}, {p:?}");
            let (y, ys) = conv2d(&x, xs, &w, ws, None, &p);
            assert_eq!(ys, Geometry::new(xs, ws, &p).out_shape(), "{what}");
            assert_close(&y, &direct(&x, xs, &w, ws, &p), Tol::Scaled(1e-5), &what);
            if y.is_empty() {
                continue;
            }
            let g = values(&mut r, y.len(), 1.0);
            let dot =
                |a: &[f32], b: &[f32]| a.iter().zip(b).map(|(u, v)| (u * v) as f64).sum::<f64>();
            let yg = dot(&y, &g);
            let (dx, dxs) = input_grad(&g, ys, &w, ws, [xs[2], xs[3]], &p);
            assert_eq!(dxs, xs, "{what}: input gradient shape");
            let dw = weight_grad(&x, xs, &g, [cout, kh, kw], &p);
            let scale = (yg.abs() + 1.0) as f32;
            assert_close(
                &[dot(&x, &dx) as f32 / scale],
                &[yg as f32 / scale],
                Tol::Abs(1e-4),
                &format!("⟨x, ∂L/∂x⟩, {what}"),
            );
            assert_close(
                &[dot(&w, &dw) as f32 / scale],
                &[yg as f32 / scale],
                Tol::Abs(1e-4),
                &format!("⟨W, ∂L/∂W⟩, {what}"),
            );
            let db = bias_grad(&g, ys);
            let want: Vec<f32> = (0..cout)
                .map(|o| {
                    (0..b)
                        .map(|i| {
                            g[(i * cout + o) * ys[2] * ys[3]..][..ys[2] * ys[3]]
                                .iter()
                                .sum::<f32>()
                        })
                        .sum()
                })
                .collect();
            assert_close(&db, &want, Tol::Scaled(1e-5), &format!("∂L/∂b, {what}"));
        }
    }
}
