//! Stride-1 convolution without a patch matrix (the 3×3 layers of Notes S9–S10): on an input
//! padded once to `[Cin, H + pt + pb, W + pl + pr]`, the input under tap (ky, kx) of every
//! output pixel is the padded plane read from offset `ky·dy·W_p + kx·dx`, if the output is
//! computed at the padded width `W_p` (its last `W_p − W'` columns are discarded). So the
//! convolution is a sum of one matrix product per tap, each reading the padded input in place:
//!
//! `out_p[:, q] = Σ_tap W[:, :, ky, kx] · x_p[:, q + ky·dy·W_p + kx·dx]`,
//! `∂L/∂W[:, :, ky, kx] = Σ_images g_p · x_p[:, · + ky·dy·W_p + kx·dx]ᵀ`,
//!
//! with `g_p` the output gradient at the padded width, zero in the extra columns. Unfolding
//! writes and reads the patch matrix, kh·kw copies of the input, through memory: for the update
//! block's GRU that is 3 MB per call. Here the product's own packing is the only copy, and it
//! stays in cache. The cost is the `W_p − W'` discarded columns (1/8 more work at 16 wide), so
//! [`eligible`] takes this path only for wide enough maps and enough input channels.

use std::cell::RefCell;

use rayon::prelude::*;

use super::geometry::{Geometry, SendPtr};

/// At most this much extra work from the discarded columns (`W_p / W'`).
const MAX_WIDTH_RATIO: f64 = 1.2;

/// More output channels than this make the forward pass faster unfolded.
const MAX_FORWARD_CHANNELS: usize = 96;

/// Fewer input channels than this make each tap's product too shallow to run at speed.
const MIN_CHANNELS: usize = 16;

/// Whether this convolution takes the shifted-product path.
pub fn eligible(g: &Geometry) -> bool {
    g.stride == [1, 1]
        && g.kh * g.kw > 1
        && g.cin >= MIN_CHANNELS
        && g.h * g.w > 0
        && g.ho > 0
        && g.wo > 0
        && (wp(g) as f64) <= MAX_WIDTH_RATIO * g.wo as f64
}

/// Whether the forward pass takes the shifted-product path: with many output channels the
/// per-tap sums `[Cout, n]` cost more than the unfolding they save (measured with cold
/// caches on the update block's and encoders' layers: unfolding is faster from 128 output
/// channels up, the shifted products from 96 down).
pub fn eligible_forward(g: &Geometry) -> bool {
    eligible(g) && g.cout <= MAX_FORWARD_CHANNELS
}

/// Padded width: the output width plus the kernel's reach.
fn wp(g: &Geometry) -> usize {
    g.wo + g.dilation[1] * (g.kw - 1)
}

/// Padded height.
fn hp(g: &Geometry) -> usize {
    g.ho + g.dilation[0] * (g.kh - 1)
}

/// Floats of one padded channel plane.
fn plane_p(g: &Geometry) -> usize {
    hp(g) * wp(g)
}

/// Offset of tap `t = ky·kw + kx` in a padded plane.
fn tap_offset(g: &Geometry, t: usize) -> usize {
    let (ky, kx) = (t / g.kw, t % g.kw);
    ky * g.dilation[0] * wp(g) + kx * g.dilation[1]
}

/// The batch padded: `[B, Cin, H_p, W_p]` plus `(kw − 1)·dx` zeros at the end, so that the
/// discarded columns of the last row still read inside the buffer.
///
/// # Shapes
/// `x` `[B, Cin, H, W]` → `[B·Cin·H_p·W_p + (kw − 1)·dx]`
fn pad_input(g: &Geometry, x: &[f32]) -> Vec<f32> {
    let (wp, plane) = (wp(g), plane_p(g));
    let [pt, pl] = g.pad;
    let mut out = vec![0f32; g.batch * g.cin * plane + (g.kw - 1) * g.dilation[1]];
    out.par_chunks_mut(plane)
        .zip(x.par_chunks(g.h * g.w))
        .for_each(|(dst, src)| {
            // At stride 1, H_p = H + pt + pb and W_p = W + pl + pr: every input row fits.
            for (y, row) in src.chunks_exact(g.w).enumerate() {
                let at = (y + pt) * wp + pl;
                dst[at..at + g.w].copy_from_slice(row);
            }
        });
    out
}

/// The convolution of `x` `[B, Cin, H, W]` by `w` `[Cout, Cin, kh, kw]` (+ `bias`), as a
/// row-major `[B, Cout, H', W']`: per band of output rows, one product per tap accumulated
/// at the padded width, then the valid columns copied out.
pub fn forward(g: &Geometry, x: &[f32], w: &[f32], bias: Option<&[f32]>) -> Vec<f32> {
    let (hw_out, wp, plane) = (g.ho * g.wo, wp(g), plane_p(g));
    let (taps, cin, cout) = (g.kh * g.kw, g.cin, g.cout);
    let xp = pad_input(g, x);
    // The kernel per tap: [kh·kw, Cout, Cin].
    let mut wt = vec![0f32; taps * cout * cin];
    for (i, k) in w.chunks_exact(taps).enumerate() {
        for (t, &v) in k.iter().enumerate() {
            wt[t * cout * cin + i] = v;
        }
    }
    let mut out = vec![0f32; g.batch * cout * hw_out];
    let dst = SendPtr(out.as_mut_ptr());
    g.for_each_band(band_rows(g), |b, oy0, oy1| {
        let n = (oy1 - oy0) * wp;
        let image = &xp[b * cin * plane..];
        BAND.with(|cell| {
            let mut acc = cell.borrow_mut();
            acc.resize(cout * n, 0.0);
            if let Some(bias) = bias {
                for (row, &v) in acc.chunks_exact_mut(n).zip(bias) {
                    row.fill(v);
                }
            }
            for t in 0..taps {
                let rhs = &image[oy0 * wp + tap_offset(g, t)..];
                // SAFETY: acc is [Cout, n]; the kernel's tap t is [Cout, Cin] at strides
                // (Cin·taps, taps); rhs is [Cin, n] at strides (H_p·W_p, 1), whose last
                // element lies inside the padded batch by the slack of `pad_input`.
                unsafe {
                    gemm::gemm(
                        cout,
                        n,
                        cin,
                        acc.as_mut_ptr(),
                        1,
                        n as isize,
                        t > 0 || bias.is_some(),
                        wt[t * cout * cin..].as_ptr(),
                        1,
                        cin as isize,
                        rhs.as_ptr(),
                        1,
                        plane as isize,
                        1.0f32,
                        1.0f32,
                        false,
                        false,
                        false,
                        gemm::Parallelism::None,
                    )
                };
            }
            // The valid W' columns of each row.
            for (c, src) in acc.chunks_exact(n).enumerate() {
                let base = (b * cout + c) * hw_out + oy0 * g.wo;
                for (y, row) in src.chunks_exact(wp).enumerate() {
                    // SAFETY: rows [oy0, oy1) of image b belong to this task alone.
                    let d = unsafe {
                        std::slice::from_raw_parts_mut(dst.ptr().add(base + y * g.wo), g.wo)
                    };
                    d.copy_from_slice(&row[..g.wo]);
                }
            }
        });
    });
    out
}

/// Rows per band: two bands per image or more, each small enough that its `[Cout, rows·W_p]`
/// sum stays in cache.
fn band_rows(g: &Geometry) -> usize {
    (BAND_ACC_FLOATS / (g.cout * wp(g))).clamp(1, g.ho.div_ceil(2).max(1))
}

/// `∂L/∂W` `[Cout, Cin, kh, kw]` from the input `x` `[B, Cin, H, W]` and the output gradient
/// `g` `[B, Cout, H', W']`: one task per tap, each summing one product per image into its
/// own `[Cout, Cin]` slice, so the threads need no reduction.
pub fn weight_grad(g: &Geometry, x: &[f32], grad: &[f32]) -> Vec<f32> {
    let (wp, plane) = (wp(g), plane_p(g));
    let (taps, cin, cout, hw_out) = (g.kh * g.kw, g.cin, g.cout, g.ho * g.wo);
    let depth = g.ho * wp;
    let xp = pad_input(g, x);
    // g at the padded width, zero in the discarded columns: [B, Cout, H'·W_p].
    let mut gp = vec![0f32; g.batch * cout * depth];
    gp.par_chunks_mut(depth)
        .zip(grad.par_chunks(hw_out))
        .for_each(|(dst, src)| {
            for (d, s) in dst.chunks_exact_mut(wp).zip(src.chunks_exact(g.wo)) {
                d[..g.wo].copy_from_slice(s);
            }
        });
    // Per tap: [Cout, Cin].
    let mut per_tap = vec![0f32; taps * cout * cin];
    per_tap
        .par_chunks_mut(cout * cin)
        .enumerate()
        .for_each(|(t, acc)| {
            for b in 0..g.batch {
                let lhs = &gp[b * cout * depth..];
                let rhs = &xp[b * cin * plane + tap_offset(g, t)..];
                // SAFETY: acc is [Cout, Cin]; lhs is image b's [Cout, depth]; rhs is read as
                // [depth, Cin] at strides (1, H_p·W_p), inside the padded batch by the slack
                // of `pad_input`.
                unsafe {
                    gemm::gemm(
                        cout,
                        cin,
                        depth,
                        acc.as_mut_ptr(),
                        1,
                        cin as isize,
                        b > 0,
                        lhs.as_ptr(),
                        1,
                        depth as isize,
                        rhs.as_ptr(),
                        plane as isize,
                        1,
                        1.0f32,
                        1.0f32,
                        false,
                        false,
                        false,
                        gemm::Parallelism::None,
                    )
                };
            }
        });
    // [kh·kw, Cout, Cin] → [Cout, Cin, kh, kw]
    let mut out = vec![0f32; cout * cin * taps];
    for (t, slice) in per_tap.chunks_exact(cout * cin).enumerate() {
        for (i, &v) in slice.iter().enumerate() {
            out[i * taps + t] = v;
        }
    }
    out
}

/// Floats of one band's `[Cout, rows·W_p]` sum.
const BAND_ACC_FLOATS: usize = 1 << 15;

thread_local! {
    /// Each rayon thread's band sum, kept between calls.
    static BAND: RefCell<Vec<f32>> = const { RefCell::new(Vec::new()) };
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flow::kernels::geometry::ConvParams;
    use crate::flow::kernels::testing::{Tol, assert_close, cases, values};
    use crate::flow::kernels::unfold;
    use rand::RngExt;

    /// The shifted products give the unfolded convolution's output and weight gradient (the
    /// unfolded path is checked against Burn in `ops::conv`): batches, dilation, asymmetric and
    /// uneven padding, a 5×5 and a 3×5 kernel, many output channels, several bands per image.
    #[test]
    fn shifted_products_match_unfolding() {
        // (batch, cin, cout, [kh, kw], dilation, ((top, bottom), (left, right)), h, w)
        let cases = [
            (2, 16, 8, [3, 3], 1, ((1, 1), (1, 1)), 12, 20),
            (3, 20, 130, [3, 3], 1, ((1, 1), (1, 1)), 9, 17),
            (2, 16, 5, [3, 3], 2, ((2, 2), (2, 2)), 10, 24),
            (1, 17, 6, [3, 3], 1, ((0, 2), (1, 0)), 7, 13),
            (2, 16, 7, [5, 5], 1, ((2, 2), (2, 2)), 8, 30),
            (1, 18, 9, [3, 5], 1, ((1, 1), (2, 2)), 6, 25),
            (2, 16, 4, [3, 3], 1, ((1, 1), (1, 1)), 70, 40),
        ];
        for (b, cin, cout, [kh, kw], d, padding, h, w) in cases {
            let p = ConvParams {
                stride: [1, 1],
                padding: [padding.0, padding.1],
                dilation: [d, d],
            };
            let what = format!("case {b} {cin} {cout} {kh}x{kw} d{d} {h}x{w}");
            check(
                &Geometry::new([b, cin, h, w], [cout, cin, kh, kw], &p),
                &what,
                7,
            );
        }
    }

    /// Property: on random stride-1 layers (channels, kernel sizes, dilations, per-side
    /// paddings, map sizes, seeded), whenever the shifted path is eligible it agrees with the
    /// unfolded one.
    #[test]
    fn shifted_products_match_unfolding_on_random_layers() {
        let mut checked = 0;
        for case in 0..60 {
            let mut r = cases("shifted vs unfolded", case);
            let (kh, kw) = (r.random_range(1..=3) * 2 - 1, r.random_range(1..=3) * 2 - 1);
            let d = r.random_range(1..=3);
            let mut pad = |k: usize| {
                (
                    r.random_range(0..=d * (k - 1)),
                    r.random_range(0..=d * (k - 1)),
                )
            };
            let padding = [pad(kh), pad(kw)];
            let p = ConvParams {
                stride: [1, 1],
                padding,
                dilation: [d, d],
            };
            let (b, cin, cout) = (
                r.random_range(1..=2),
                r.random_range(16..=24),
                r.random_range(1..=20),
            );
            let (h, w) = (r.random_range(1..=20), r.random_range(12..=40));
            let g = Geometry::new([b, cin, h, w], [cout, cin, kh, kw], &p);
            if !eligible(&g) {
                continue;
            }
            checked += 1;
            check(&g, &format!("random case {case}: {g:?}"), case as usize);
        }
        assert!(checked >= 20, "only {checked} eligible cases");
    }

    /// Forward (with and without bias) and weight gradient of both paths.
    fn check(g: &Geometry, what: &str, seed: usize) {
        let mut r = cases("shifted inputs", seed as u64);
        let x = values(&mut r, g.batch * g.cin * g.h * g.w, 1.0);
        let wt = values(&mut r, g.cout * g.k(), 1.0);
        let bias = values(&mut r, g.cout, 1.0);
        let grad = values(&mut r, g.batch * g.cout * g.ho * g.wo, 1.0);
        let tol = Tol::Scaled(1e-5);
        assert_close(
            &forward(g, &x, &wt, Some(&bias)),
            &unfold::forward(g, &x, &wt, Some(&bias)),
            tol,
            &format!("forward, {what}"),
        );
        assert_close(
            &forward(g, &x, &wt, None),
            &unfold::forward(g, &x, &wt, None),
            tol,
            &format!("forward without bias, {what}"),
        );
        assert_close(
            &weight_grad(g, &x, &grad),
            &unfold::weight_grad(g, &x, &grad),
            tol,
            &format!("∂L/∂W, {what}"),
        );
    }

    /// The network's layers go where they run fastest: the GRU's and the update block's 3×3
    /// layers on shifted products (its wide forward layers unfolded), and the 7×7 on a 16-wide
    /// map, the dilated DASPP branches, strided and 1×1 layers, and shallow inputs unfolded.
    #[test]
    fn layers_take_the_intended_path() {
        let geometry = |cin, cout, k, s, d, p, side| {
            Geometry::new(
                [2, cin, side, side],
                [cout, cin, k, k],
                &ConvParams {
                    stride: [s, s],
                    padding: [(p, p), (p, p)],
                    dilation: [d, d],
                },
            )
        };
        let gru_zr = geometry(176, 128, 3, 1, 1, 1, 16);
        assert!(eligible(&gru_zr) && !eligible_forward(&gru_zr));
        let gru_q = geometry(176, 64, 3, 1, 1, 1, 16);
        assert!(eligible(&gru_q) && eligible_forward(&gru_q));
        for unfolded in [
            geometry(2, 32, 7, 1, 1, 3, 16),
            geometry(64, 64, 3, 1, 12, 12, 16),
            geometry(32, 48, 3, 2, 1, 1, 64),
            geometry(96, 576, 1, 1, 1, 0, 16),
            geometry(8, 16, 3, 1, 1, 1, 64),
        ] {
            assert!(!eligible(&unfolded), "{unfolded:?}");
        }
    }
}
