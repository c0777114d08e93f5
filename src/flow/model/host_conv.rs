//! Convolution for inference on the CPU (every layer of Notes S9–S10): the same cross-correlation
//! as `burn::tensor::module::conv2d`, computed as one matrix product per band of output rows.
//!
//! The CPU backend lays every input out channel-last, builds its unfolded patch matrix (im2col)
//! in tiles of 512 pixels, re-packs the weights for every tile and scatters each product back
//! channel-first. Here the unfolding stays channel-first, so every patch row is a shifted copy
//! of an input row (a plain `copy_from_slice` at stride 1), a 1×1 convolution reads its input
//! in place, and the product writes straight into the output: `out[:, band] = W · cols(band)`
//! with `W` `[Cout, Cin·kh·kw]` exactly as stored. Bands run in parallel on rayon.
//!
//! The non-autodiff CPU device takes this path directly (see [`conv_forward`]); training reaches
//! the same kernels through the differentiable operation of [`super::train_conv`]; other devices
//! keep burn's convolution.

use std::cell::RefCell;

use burn::nn::PaddingConfig2d;
use burn::nn::conv::Conv2d;
use burn::prelude::*;
use burn::tensor::DType;
use burn::tensor::module::conv2d;
use burn::tensor::ops::ConvOptions;
use rayon::prelude::*;

pub use super::act::Act;
use super::flex_bridge::HostView;
use super::train_conv::conv2d_train;

/// Floats of one band's patch matrix: big enough for the product to run at full speed (measured
/// best among 2^17, 2^19 and 2^21 on the update block's and encoders' layers), small enough to
/// stay in cache.
const BAND_FLOATS: usize = 1 << 19;

/// `c.forward(x)`, on the host kernel when `x` lives on the non-autodiff CPU device.
///
/// # Shapes
/// `[B, Cin, H, W]` → `[B, Cout, H', W']`
pub fn conv_forward(c: &Conv2d, x: Tensor<4>) -> Tensor<4> {
    conv_act(c, x, Act::Identity)
}

/// `act(c.forward(x))`: the layer and its activation as one operation on the CPU backend.
///
/// # Shapes
/// `[B, Cin, H, W]` → `[B, Cout, H', W']`
pub fn conv_act(c: &Conv2d, x: Tensor<4>, act: Act) -> Tensor<4> {
    match c.padding {
        PaddingConfig2d::Explicit(top, left, bottom, right) if c.groups == 1 => conv2d_act(
            x,
            c.weight.val(),
            c.bias.as_ref().map(|b| b.val()),
            ConvOptions::new_with_padding(c.stride, [(top, bottom), (left, right)], c.dilation, 1),
            act,
        ),
        _ => act.apply_tensor(c.forward(x)),
    }
}

/// `burn::tensor::module::conv2d`, on the host kernel when every tensor lives on the
/// non-autodiff CPU device and the convolution is ungrouped; under autodiff, through
/// [`conv2d_train`] (host kernels for the stride-1 layers, burn's for the rest).
///
/// # Shapes
/// `x` `[B, Cin, H, W]`, `weight` `[Cout, Cin, kh, kw]`, `bias` `[Cout]` → `[B, Cout, H', W']`
pub fn conv2d_forward(
    x: Tensor<4>,
    weight: Tensor<4>,
    bias: Option<Tensor<1>>,
    options: ConvOptions<2>,
) -> Tensor<4> {
    conv2d_act(x, weight, bias, options, Act::Identity)
}

/// `act(conv2d(x, weight, bias, options))`, as [`conv2d_forward`] with the activation inside.
pub fn conv2d_act(
    x: Tensor<4>,
    weight: Tensor<4>,
    bias: Option<Tensor<1>>,
    options: ConvOptions<2>,
    act: Act,
) -> Tensor<4> {
    if x.is_autodiff() || weight.is_autodiff() {
        return conv2d_train(x, weight, bias, options, act);
    }
    let f32s = x.dtype() == DType::F32
        && weight.dtype() == DType::F32
        && bias.as_ref().is_none_or(|b| b.dtype() == DType::F32);
    let host = options.groups == 1
        && f32s
        && x.device() == Device::flex()
        && weight.dims()[1] == x.dims()[1];
    if !host {
        return act.apply_tensor(conv2d(x, weight, bias, options));
    }
    // Read in place; unreachable fallbacks for the CPU f32 tensors checked above.
    let (Some(xv), Some(wv)) = (HostView::of(x.clone()), HostView::of(weight.clone())) else {
        return act.apply_tensor(conv2d(x, weight, bias, options));
    };
    let bv = match bias.clone().map(HostView::of) {
        None => None,
        Some(Some(b)) => Some(b),
        Some(None) => return act.apply_tensor(conv2d(x, weight, bias, options)),
    };
    let bias = bv.as_ref().map(|b| b.values());
    let (mut out, shape) = conv_host(xv.values(), xv.dims, wv.values(), wv.dims, bias, &options);
    act.apply(&mut out);
    Tensor::from_data(TensorData::new(out, shape), &x.device())
}

/// An ungrouped convolution of host values: `x` `[B, Cin, H, W]` by `w` `[Cout, Cin, kh, kw]`
/// (+ `bias` `[Cout]`), returned with its shape `[B, Cout, H', W']`.
pub fn conv_host(
    x: &[f32],
    xs: [usize; 4],
    w: &[f32],
    ws: [usize; 4],
    bias: Option<&[f32]>,
    options: &ConvOptions<2>,
) -> (Vec<f32>, [usize; 4]) {
    let geometry = Geometry::new(xs, ws, options);
    (geometry.run(x, w, bias), geometry.out_shape())
}

/// ∂L/∂W of an ungrouped convolution of host values, given its input `x` `[B, Cin, H, W]` and
/// the gradient `g` `[B, Cout, H', W']` of its output: `Σ_images g · colsᵀ`, the forward
/// unfolding transposed. Returns `[Cout, Cin, kh, kw]`.
pub fn weight_grad_host(
    x: &[f32],
    xs: [usize; 4],
    g: &[f32],
    [cout, kh, kw]: [usize; 3],
    options: &ConvOptions<2>,
) -> Vec<f32> {
    Geometry::new(xs, [cout, xs[1], kh, kw], options).weight_grad(x, g)
}

/// Sizes of one convolution.
#[derive(Clone, Copy, Debug)]
pub(super) struct Geometry {
    pub(super) batch: usize,
    pub(super) cin: usize,
    pub(super) h: usize,
    pub(super) w: usize,
    pub(super) cout: usize,
    pub(super) kh: usize,
    pub(super) kw: usize,
    pub(super) stride: [usize; 2],
    /// (top, left)
    pub(super) pad: [usize; 2],
    pub(super) dilation: [usize; 2],
    pub(super) ho: usize,
    pub(super) wo: usize,
}

impl Geometry {
    pub(super) fn new(
        [batch, cin, h, w]: [usize; 4],
        [cout, _, kh, kw]: [usize; 4],
        o: &ConvOptions<2>,
    ) -> Self {
        let out = |size: usize, (p0, p1): (usize, usize), k: usize, s: usize, d: usize| {
            let span = d * (k - 1) + 1;
            (size + p0 + p1).checked_sub(span).map_or(0, |v| v / s + 1)
        };
        Self {
            batch,
            cin,
            h,
            w,
            cout,
            kh,
            kw,
            stride: o.stride,
            pad: [o.padding[0].0, o.padding[1].0],
            dilation: o.dilation,
            ho: out(h, o.padding[0], kh, o.stride[0], o.dilation[0]),
            wo: out(w, o.padding[1], kw, o.stride[1], o.dilation[1]),
        }
    }

    fn out_shape(&self) -> [usize; 4] {
        [self.batch, self.cout, self.ho, self.wo]
    }

    /// Patch length: one column of the unfolded input.
    fn k(&self) -> usize {
        self.cin * self.kh * self.kw
    }

    /// A 1×1, stride-1, unpadded convolution reads its input as the patch matrix.
    fn is_pointwise(&self) -> bool {
        self.kh == 1
            && self.kw == 1
            && self.stride == [1, 1]
            && self.pad == [0, 0]
            && (self.ho, self.wo) == (self.h, self.w)
    }

    /// The convolution of `x` `[B, Cin, H, W]` by `w` `[Cout, Cin, kh, kw]` (+ `bias`), as a
    /// row-major `[B, Cout, H', W']`: by shifted products (`super::shifted_conv`) where they
    /// are faster, else unfolded.
    fn run(&self, x: &[f32], w: &[f32], bias: Option<&[f32]>) -> Vec<f32> {
        let hw_out = self.ho * self.wo;
        if hw_out == 0 || self.cout == 0 {
            return vec![0f32; self.batch * self.cout * hw_out];
        }
        if self.k() == 0 {
            // No input channels: the output is the bias.
            let mut out = vec![0f32; self.batch * self.cout * hw_out];
            if let Some(b) = bias {
                for (c, plane) in out.chunks_exact_mut(hw_out).enumerate() {
                    plane.fill(b[c % self.cout]);
                }
            }
            return out;
        }
        if self.shifted_forward() {
            return self.run_shifted(x, w, bias);
        }
        self.run_unfold(x, w, bias)
    }

    /// [`Self::run`] by unfolding: one product per band of output rows, in parallel.
    pub(super) fn run_unfold(&self, x: &[f32], w: &[f32], bias: Option<&[f32]>) -> Vec<f32> {
        let hw_out = self.ho * self.wo;
        let mut out = vec![0f32; self.batch * self.cout * hw_out];
        let dst = SendPtr(out.as_mut_ptr());
        self.for_each_band(self.bands().0, |b, oy0, oy1| {
            // SAFETY: every task writes the pixels of its own rows [oy0, oy1) of its own image,
            // so no two tasks touch the same element, and `out` outlives the loop.
            unsafe { self.band(x, w, bias, b, oy0, oy1, dst) };
        });
        out
    }

    /// Runs `f(b, oy0, oy1)` for every band of `rows` output rows `[oy0, oy1)` of every image
    /// `b`, in parallel.
    pub(super) fn for_each_band(&self, rows: usize, f: impl Fn(usize, usize, usize) + Sync) {
        let bands = self.ho.div_ceil(rows);
        (0..self.batch * bands).into_par_iter().for_each(|task| {
            let (b, oy0) = (task / bands, (task % bands) * rows);
            f(b, oy0, (oy0 + rows).min(self.ho));
        });
    }

    /// Rows per band and bands per image.
    fn bands(&self) -> (usize, usize) {
        // At least two bands per image, so that one image still feeds two threads.
        let rows = (BAND_FLOATS / (self.k() * self.wo)).clamp(1, self.ho.div_ceil(2).max(1));
        (rows, self.ho.div_ceil(rows))
    }

    /// `∂L/∂W` `[Cout, Cin·kh·kw]`, `Σ g · colsᵀ` over the batch: by shifted products where the
    /// layer allows them (always faster there), else unfolded.
    fn weight_grad(&self, x: &[f32], g: &[f32]) -> Vec<f32> {
        let (k, cout) = (self.k(), self.cout);
        if self.ho * self.wo == 0 || k == 0 || cout == 0 {
            return vec![0f32; cout * k];
        }
        if self.shifted() {
            return self.weight_grad_shifted(x, g);
        }
        self.weight_grad_unfold(x, g)
    }

    /// [`Self::weight_grad`] by unfolding: one partial sum per thread over bands of output
    /// rows, added at the end.
    pub(super) fn weight_grad_unfold(&self, x: &[f32], g: &[f32]) -> Vec<f32> {
        let (k, cout) = (self.k(), self.cout);
        let (rows, bands_per_image) = self.bands();
        (0..self.batch * bands_per_image)
            .into_par_iter()
            .fold(
                || vec![0f32; cout * k],
                |mut acc, task| {
                    let (b, band) = (task / bands_per_image, task % bands_per_image);
                    let oy0 = band * rows;
                    self.band_weight_grad(x, g, b, oy0, (oy0 + rows).min(self.ho), &mut acc);
                    acc
                },
            )
            .reduce(
                || vec![0f32; cout * k],
                |mut a, b| {
                    a.iter_mut().zip(&b).for_each(|(u, v)| *u += v);
                    a
                },
            )
    }

    /// Adds `g(rows [oy0, oy1) of image b) · cols(band)ᵀ` to `acc` `[Cout, k]`.
    fn band_weight_grad(
        &self,
        x: &[f32],
        g: &[f32],
        b: usize,
        oy0: usize,
        oy1: usize,
        acc: &mut [f32],
    ) {
        let (hw_in, hw_out, k) = (self.h * self.w, self.ho * self.wo, self.k());
        let n = (oy1 - oy0) * self.wo;
        let p0 = oy0 * self.wo;
        let image = &x[b * self.cin * hw_in..(b + 1) * self.cin * hw_in];
        let grad = &g[b * self.cout * hw_out + p0..];
        // rhs = colsᵀ [n, k]: element (p, kk) at rhs[p·rs + kk·cs].
        let product = |rhs: *const f32, rhs_cs: usize, acc: &mut [f32]| unsafe {
            // SAFETY: acc is [Cout, k]; grad rows hold n pixels at stride H'·W'; rhs spans
            // k columns of n pixels at the given strides, inside its slice.
            gemm::gemm(
                self.cout,
                k,
                n,
                acc.as_mut_ptr(),
                1,
                k as isize,
                true,
                grad.as_ptr(),
                1,
                hw_out as isize,
                rhs,
                rhs_cs as isize,
                1,
                1.0f32,
                1.0f32,
                false,
                false,
                false,
                gemm::Parallelism::None,
            )
        };
        self.with_patches(image, oy0, oy1, |cols, stride| product(cols, stride, acc));
    }

    /// Output rows `[oy0, oy1)` of image `b`.
    ///
    /// # Safety
    /// `dst` points at the `[B, Cout, H', W']` output, and no other thread writes these rows.
    #[allow(clippy::too_many_arguments)]
    unsafe fn band(
        &self,
        x: &[f32],
        w: &[f32],
        bias: Option<&[f32]>,
        b: usize,
        oy0: usize,
        oy1: usize,
        dst: SendPtr,
    ) {
        let (hw_in, hw_out, k) = (self.h * self.w, self.ho * self.wo, self.k());
        let n = (oy1 - oy0) * self.wo;
        let p0 = oy0 * self.wo;
        let image = &x[b * self.cin * hw_in..(b + 1) * self.cin * hw_in];
        // SAFETY (all of the raw pointer uses below): the caller gives this band to this thread
        // alone; offsets stay inside image b's [Cout, H'·W'] block.
        let out = unsafe { dst.0.add(b * self.cout * hw_out + p0) };
        if let Some(bias) = bias {
            for (c, &v) in bias.iter().enumerate().take(self.cout) {
                let row = unsafe { std::slice::from_raw_parts_mut(out.add(c * hw_out), n) };
                row.fill(v);
            }
        }
        let product = |rhs: *const f32, rhs_rs: usize| unsafe {
            gemm::gemm(
                self.cout,
                n,
                k,
                out,
                1,
                hw_out as isize,
                bias.is_some(),
                w.as_ptr(),
                1,
                k as isize,
                rhs,
                1,
                rhs_rs as isize,
                1.0f32,
                1.0f32,
                false,
                false,
                false,
                gemm::Parallelism::None,
            )
        };
        self.with_patches(image, oy0, oy1, product);
    }

    /// Calls `product(cols, stride)` with the patch matrix `[Cin·kh·kw, n]` of output rows
    /// `[oy0, oy1)` of `image`, rows `stride` floats apart: the image itself for a pointwise
    /// convolution, else this thread's buffer, unfolded.
    fn with_patches<R>(
        &self,
        image: &[f32],
        oy0: usize,
        oy1: usize,
        product: impl FnOnce(*const f32, usize) -> R,
    ) -> R {
        if self.is_pointwise() {
            return product(image[oy0 * self.wo..].as_ptr(), self.h * self.w);
        }
        let (k, n) = (self.k(), (oy1 - oy0) * self.wo);
        PATCHES.with(|cell| {
            let mut cols = cell.borrow_mut();
            if cols.len() < k * n {
                cols.resize(k * n, 0.0);
            }
            self.unfold(image, oy0, oy1, &mut cols[..k * n]);
            product(cols.as_ptr(), n)
        })
    }

    /// The patch matrix of output rows `[oy0, oy1)`: `cols[(c·kh + ky)·kw + kx][p]` is the input
    /// under tap (ky, kx) of channel c for output pixel p of the band, zero outside the image.
    ///
    /// # Shapes
    /// `image` `[Cin, H, W]` → `cols` `[Cin·kh·kw, (oy1 − oy0)·W']`
    fn unfold(&self, image: &[f32], oy0: usize, oy1: usize, cols: &mut [f32]) {
        let n = (oy1 - oy0) * self.wo;
        let [sy, sx] = self.stride;
        let [dy, dx] = self.dilation;
        let [py, px] = self.pad;
        for (row, dst) in cols.chunks_exact_mut(n).enumerate() {
            let (c, tap) = (row / (self.kh * self.kw), row % (self.kh * self.kw));
            let (ky, kx) = (tap / self.kw, tap % self.kw);
            let plane = &image[c * self.h * self.w..(c + 1) * self.h * self.w];
            // Output columns whose input column ox·sx + kx·dx − px lies inside [0, W).
            let shift = (kx * dx) as isize - px as isize;
            let lo = ((-shift).max(0) as usize).div_ceil(sx).min(self.wo);
            let hi = if (self.w as isize) <= shift {
                lo
            } else {
                ((self.w as isize - shift - 1) as usize / sx + 1).clamp(lo, self.wo)
            };
            for (oy, seg) in (oy0..oy1).zip(dst.chunks_exact_mut(self.wo)) {
                let iy = (oy * sy + ky * dy) as isize - py as isize;
                if iy < 0 || iy >= self.h as isize {
                    seg.fill(0.0);
                    continue;
                }
                let src = &plane[iy as usize * self.w..(iy as usize + 1) * self.w];
                seg[..lo].fill(0.0);
                seg[hi..].fill(0.0);
                if lo == hi {
                    continue;
                }
                let first = (lo * sx) as isize + shift; // ≥ 0 by the choice of lo
                if sx == 1 {
                    let first = first as usize;
                    seg[lo..hi].copy_from_slice(&src[first..first + (hi - lo)]);
                } else {
                    for (i, v) in seg[lo..hi].iter_mut().enumerate() {
                        *v = src[first as usize + i * sx];
                    }
                }
            }
        }
    }
}

thread_local! {
    /// Each rayon thread's patch matrix, kept between calls.
    static PATCHES: RefCell<Vec<f32>> = const { RefCell::new(Vec::new()) };
}

/// The output pointer, shared by the band tasks.
#[derive(Clone, Copy)]
pub(super) struct SendPtr(pub(super) *mut f32);
// SAFETY: the tasks write disjoint rows (see `Geometry::run`).
unsafe impl Send for SendPtr {}
unsafe impl Sync for SendPtr {}

impl SendPtr {
    /// The pointer; a method, so that closures capture the `Send` wrapper, not its field.
    pub(super) fn ptr(self) -> *mut f32 {
        self.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::Distribution;

    /// The host kernels (unfolding and Winograd) give burn's numbers for every kind of
    /// convolution in the network: 3×3, strided, dilated beyond the image, 7×7, 1×1 with and
    /// without stride, no bias, asymmetric padding, batches, and maps smaller than the kernel.
    #[test]
    fn host_convolution_matches_burn() {
        let dev = Device::flex();
        // (cin, cout, kernel, stride, dilation, padding (top, bottom, left, right), h, w, batch, bias)
        let cases = [
            (5, 7, 3, 1, 1, (1, 1, 1, 1), 9, 11, 2, true),
            (4, 6, 3, 2, 1, (1, 1, 1, 1), 10, 13, 1, true),
            (3, 8, 7, 2, 1, (3, 3, 3, 3), 16, 20, 2, true),
            (6, 6, 3, 1, 6, (6, 6, 6, 6), 5, 7, 1, true),
            (6, 5, 3, 1, 18, (18, 18, 18, 18), 4, 6, 2, false),
            (9, 4, 1, 1, 1, (0, 0, 0, 0), 6, 8, 2, true),
            (9, 4, 1, 2, 1, (0, 0, 0, 0), 7, 9, 1, true),
            // 1×1 with end padding only: not a plain product of the input.
            (5, 7, 1, 1, 1, (0, 2, 0, 1), 9, 11, 2, true),
            (2, 3, 7, 1, 1, (3, 3, 3, 3), 3, 4, 1, true),
            (3, 4, 3, 1, 1, (0, 2, 1, 0), 6, 5, 1, true),
            (2, 3, 3, 3, 2, (0, 0, 0, 0), 12, 14, 1, false),
            // More channels: odd sizes, asymmetric and no padding, 1×1 maps.
            (8, 9, 3, 1, 1, (1, 1, 1, 1), 7, 5, 2, true),
            (12, 8, 3, 1, 1, (0, 2, 1, 0), 5, 6, 1, false),
            (8, 8, 3, 1, 1, (1, 1, 1, 1), 1, 1, 1, true),
            (9, 10, 3, 1, 1, (0, 0, 0, 0), 3, 8, 2, true),
            (16, 24, 3, 1, 1, (1, 1, 1, 1), 23, 31, 1, true),
        ];
        for (cin, cout, k, s, d, (pt, pb, pl, pr), h, w, b, with_bias) in cases {
            let x = Tensor::<4>::random([b, cin, h, w], Distribution::Normal(0.0, 1.0), &dev);
            let wt = Tensor::<4>::random([cout, cin, k, k], Distribution::Normal(0.0, 1.0), &dev);
            let bias = with_bias
                .then(|| Tensor::<1>::random([cout], Distribution::Normal(0.0, 1.0), &dev));
            let opts = ConvOptions::new_with_padding([s, s], [(pt, pb), (pl, pr)], [d, d], 1);
            let want = conv2d(x.clone(), wt.clone(), bias.clone(), opts.clone());
            let got = conv2d_forward(x, wt, bias, opts);
            assert_eq!(got.dims(), want.dims(), "case {cin} {cout} {k} {s} {d}");
            let diff: f32 = (got - want).abs().max().into_scalar();
            assert!(
                diff < 1e-4,
                "case {cin} {cout} {k} {s} {d}: max difference {diff}"
            );
        }
    }

    /// A map larger than one band (several bands per image, on several threads) still matches.
    #[test]
    fn host_convolution_matches_burn_across_bands() {
        let dev = Device::flex();
        let (cin, cout, h, w) = (64, 16, 70, 90);
        let x = Tensor::<4>::random([2, cin, h, w], Distribution::Normal(0.0, 1.0), &dev);
        let wt = Tensor::<4>::random([cout, cin, 3, 3], Distribution::Normal(0.0, 0.1), &dev);
        let bias = Tensor::<1>::random([cout], Distribution::Normal(0.0, 1.0), &dev);
        let opts = ConvOptions::new([1, 1], [1, 1], [1, 1], 1);
        let g = Geometry::new([2, cin, h, w], [cout, cin, 3, 3], &opts);
        assert!(
            g.ho.div_ceil((BAND_FLOATS / (g.k() * g.wo)).max(1)) > 2,
            "one band only"
        );
        let want = conv2d(x.clone(), wt.clone(), Some(bias.clone()), opts.clone());
        let got = conv2d_forward(x, wt, Some(bias), opts);
        let diff: f32 = (got - want).abs().max().into_scalar();
        assert!(diff < 1e-4, "max difference {diff}");
    }

    /// The module form uses the layer's own stride, dilation and explicit padding, and falls
    /// back to burn (same numbers) under autodiff.
    #[test]
    fn module_form_matches_the_layer() {
        let dev = Device::flex();
        let layer = super::super::blocks::conv(4, 6, 3, 2, 1, &dev);
        let x = Tensor::<4>::random([1, 4, 12, 10], Distribution::Normal(0.0, 1.0), &dev);
        let diff: f32 = (conv_forward(&layer, x.clone()) - layer.forward(x))
            .abs()
            .max()
            .into_scalar();
        assert!(diff < 1e-4, "max difference {diff}");
        let ad = dev.autodiff();
        let layer = super::super::blocks::conv(4, 6, 3, 1, 2, &ad);
        let x = Tensor::<4>::random([1, 4, 9, 9], Distribution::Normal(0.0, 1.0), &ad);
        let y = conv_forward(&layer, x.clone());
        assert!(y.is_autodiff());
        let diff: f32 = (y - layer.forward(x)).abs().max().into_scalar();
        assert!(diff < 1e-5, "max difference {diff}");
    }
}
