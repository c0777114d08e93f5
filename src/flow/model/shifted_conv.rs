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
//! [`Geometry::shifted`] takes this path only for wide enough maps and enough input channels.

use std::cell::RefCell;

use rayon::prelude::*;

use super::host_conv::{Geometry, SendPtr};

/// At most this much extra work from the discarded columns (`W_p / W'`).
const MAX_WIDTH_RATIO: f64 = 1.2;

/// More output channels than this make the forward pass faster unfolded.
const MAX_FORWARD_CHANNELS: usize = 96;

/// Fewer input channels than this make each tap's product too shallow to run at speed.
const MIN_CHANNELS: usize = 16;

impl Geometry {
    /// Whether this convolution takes the shifted-product path.
    pub(super) fn shifted(&self) -> bool {
        self.stride == [1, 1]
            && self.kh * self.kw > 1
            && self.cin >= MIN_CHANNELS
            && self.h * self.w > 0
            && self.ho > 0
            && self.wo > 0
            && (self.wp() as f64) <= MAX_WIDTH_RATIO * self.wo as f64
    }

    /// Whether the forward pass takes the shifted-product path: with many output channels the
    /// per-tap sums `[Cout, n]` cost more than the unfolding they save (measured with cold
    /// caches on the update block's and encoders' layers: unfolding is faster from 128 output
    /// channels up, the shifted products from 96 down).
    pub(super) fn shifted_forward(&self) -> bool {
        self.shifted() && self.cout <= MAX_FORWARD_CHANNELS
    }

    /// Padded width: the output width plus the kernel's reach.
    fn wp(&self) -> usize {
        self.wo + self.dilation[1] * (self.kw - 1)
    }

    /// Padded height.
    fn hp(&self) -> usize {
        self.ho + self.dilation[0] * (self.kh - 1)
    }

    /// Floats of one padded channel plane.
    fn plane_p(&self) -> usize {
        self.hp() * self.wp()
    }

    /// Offset of tap `t = ky·kw + kx` in a padded plane.
    fn tap_offset(&self, t: usize) -> usize {
        let (ky, kx) = (t / self.kw, t % self.kw);
        ky * self.dilation[0] * self.wp() + kx * self.dilation[1]
    }

    /// The batch padded: `[B, Cin, H_p, W_p]` plus `(kw − 1)·dx` zeros at the end, so that the
    /// discarded columns of the last row still read inside the buffer.
    ///
    /// # Shapes
    /// `x` `[B, Cin, H, W]` → `[B·Cin·H_p·W_p + (kw − 1)·dx]`
    fn pad_input(&self, x: &[f32]) -> Vec<f32> {
        let (wp, plane) = (self.wp(), self.plane_p());
        let [pt, pl] = self.pad;
        let mut out = vec![0f32; self.batch * self.cin * plane + (self.kw - 1) * self.dilation[1]];
        out.par_chunks_mut(plane)
            .zip(x.par_chunks(self.h * self.w))
            .for_each(|(dst, src)| {
                // At stride 1, H_p = H + pt + pb and W_p = W + pl + pr: every input row fits.
                for (y, row) in src.chunks_exact(self.w).enumerate() {
                    let at = (y + pt) * wp + pl;
                    dst[at..at + self.w].copy_from_slice(row);
                }
            });
        out
    }

    /// The convolution of `x` `[B, Cin, H, W]` by `w` `[Cout, Cin, kh, kw]` (+ `bias`), as a
    /// row-major `[B, Cout, H', W']`: per band of output rows, one product per tap accumulated
    /// at the padded width, then the valid columns copied out.
    pub(super) fn run_shifted(&self, x: &[f32], w: &[f32], bias: Option<&[f32]>) -> Vec<f32> {
        let (hw_out, wp, plane) = (self.ho * self.wo, self.wp(), self.plane_p());
        let (taps, cin, cout) = (self.kh * self.kw, self.cin, self.cout);
        let xp = self.pad_input(x);
        // The kernel per tap: [kh·kw, Cout, Cin].
        let mut wt = vec![0f32; taps * cout * cin];
        for (i, k) in w.chunks_exact(taps).enumerate() {
            for (t, &v) in k.iter().enumerate() {
                wt[t * cout * cin + i] = v;
            }
        }
        let mut out = vec![0f32; self.batch * cout * hw_out];
        let dst = SendPtr(out.as_mut_ptr());
        self.for_each_band(self.band_rows_shifted(), |b, oy0, oy1| {
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
                    let rhs = &image[oy0 * wp + self.tap_offset(t)..];
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
                    let base = (b * cout + c) * hw_out + oy0 * self.wo;
                    for (y, row) in src.chunks_exact(wp).enumerate() {
                        // SAFETY: rows [oy0, oy1) of image b belong to this task alone.
                        let d = unsafe {
                            std::slice::from_raw_parts_mut(
                                dst.ptr().add(base + y * self.wo),
                                self.wo,
                            )
                        };
                        d.copy_from_slice(&row[..self.wo]);
                    }
                }
            });
        });
        out
    }

    /// Rows per band: two bands per image or more, each small enough that its `[Cout, rows·W_p]`
    /// sum stays in cache.
    fn band_rows_shifted(&self) -> usize {
        (BAND_ACC_FLOATS / (self.cout * self.wp())).clamp(1, self.ho.div_ceil(2).max(1))
    }

    /// `∂L/∂W` `[Cout, Cin, kh, kw]` from the input `x` `[B, Cin, H, W]` and the output gradient
    /// `g` `[B, Cout, H', W']`: one task per tap, each summing one product per image into its
    /// own `[Cout, Cin]` slice, so the threads need no reduction.
    pub(super) fn weight_grad_shifted(&self, x: &[f32], g: &[f32]) -> Vec<f32> {
        let (wp, plane) = (self.wp(), self.plane_p());
        let (taps, cin, cout, hw_out) = (self.kh * self.kw, self.cin, self.cout, self.ho * self.wo);
        let depth = self.ho * wp;
        let xp = self.pad_input(x);
        // g at the padded width, zero in the discarded columns: [B, Cout, H'·W_p].
        let mut gp = vec![0f32; self.batch * cout * depth];
        gp.par_chunks_mut(depth)
            .zip(g.par_chunks(hw_out))
            .for_each(|(dst, src)| {
                for (d, s) in dst.chunks_exact_mut(wp).zip(src.chunks_exact(self.wo)) {
                    d[..self.wo].copy_from_slice(s);
                }
            });
        // Per tap: [Cout, Cin].
        let mut per_tap = vec![0f32; taps * cout * cin];
        per_tap
            .par_chunks_mut(cout * cin)
            .enumerate()
            .for_each(|(t, acc)| {
                for b in 0..self.batch {
                    let lhs = &gp[b * cout * depth..];
                    let rhs = &xp[b * cin * plane + self.tap_offset(t)..];
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
    use burn::tensor::ops::ConvOptions;

    fn values(n: usize, seed: usize) -> Vec<f32> {
        (0..n)
            .map(|i| (((i + seed) * 7919) % 1013) as f32 / 506.5 - 1.0)
            .collect()
    }

    /// The shifted products give the unfolded convolution's output and weight gradient (the
    /// unfolded path is checked against burn in `host_conv`): batches, dilation, asymmetric and
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
            let opts = ConvOptions::new_with_padding([1, 1], [padding.0, padding.1], [d, d], 1);
            let g = Geometry::new([b, cin, h, w], [cout, cin, kh, kw], &opts);
            let x = values(b * cin * h * w, 1);
            let wt = values(cout * cin * kh * kw, 2);
            let bias = values(cout, 3);
            let grad = values(b * cout * g.ho * g.wo, 4);
            let close = |a: &[f32], e: &[f32], what: &str| {
                assert_eq!(a.len(), e.len(), "{what}: length");
                let diff = a
                    .iter()
                    .zip(e)
                    .map(|(u, v)| (u - v).abs())
                    .fold(0.0, f32::max);
                let scale = e.iter().map(|v| v.abs()).fold(1.0, f32::max);
                assert!(
                    diff <= 1e-5 * scale,
                    "{what} (case {b} {cin} {cout} {kh}x{kw} d{d} {h}x{w}): difference {diff}"
                );
            };
            close(
                &g.run_shifted(&x, &wt, Some(&bias)),
                &g.run_unfold(&x, &wt, Some(&bias)),
                "forward",
            );
            close(
                &g.run_shifted(&x, &wt, None),
                &g.run_unfold(&x, &wt, None),
                "forward, no bias",
            );
            close(
                &g.weight_grad_shifted(&x, &grad),
                &g.weight_grad_unfold(&x, &grad),
                "∂L/∂W",
            );
        }
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
                &ConvOptions::new([s, s], [p, p], [d, d], 1),
            )
        };
        let gru_zr = geometry(176, 128, 3, 1, 1, 1, 16);
        assert!(gru_zr.shifted() && !gru_zr.shifted_forward());
        let gru_q = geometry(176, 64, 3, 1, 1, 1, 16);
        assert!(gru_q.shifted() && gru_q.shifted_forward());
        for unfolded in [
            geometry(2, 32, 7, 1, 1, 3, 16),
            geometry(64, 64, 3, 1, 12, 12, 16),
            geometry(32, 48, 3, 2, 1, 1, 64),
            geometry(96, 576, 1, 1, 1, 0, 16),
            geometry(8, 16, 3, 1, 1, 1, 64),
        ] {
            assert!(!unfolded.shifted(), "{unfolded:?}");
        }
    }
}
