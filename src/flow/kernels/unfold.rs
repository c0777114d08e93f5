//! Convolution by unfolding (im2col), channel-first: for every band of output rows, the patch
//! matrix `cols` `[Cin·kh·kw, n]` (each patch row a shifted copy of an input row, a plain
//! `copy_from_slice` at stride 1) and one matrix product, written straight into the output:
//! `out[:, band] = W · cols(band)` with `W` `[Cout, Cin·kh·kw]` exactly as stored. The weight
//! gradient is the same unfolding transposed, `∂L/∂W = Σ g(band) · cols(band)ᵀ`. A 1×1,
//! stride-1, unpadded convolution reads its input in place as the patch matrix.
//!
//! (The CPU backend's own convolution lays the input out channel-last, builds its patch matrix
//! in tiles of 512 pixels, re-packs the weights for every tile and scatters each product back
//! channel-first.)

use std::cell::RefCell;

use rayon::prelude::*;

use super::geometry::{Geometry, SendPtr};

/// Floats of one band's patch matrix: big enough for the product to run at full speed (measured
/// best among 2^17, 2^19 and 2^21 on the update block's and encoders' layers), small enough to
/// stay in cache.
pub const BAND_FLOATS: usize = 1 << 19;

/// The convolution of `x` `[B, Cin, H, W]` by `w` `[Cout, Cin, kh, kw]` (+ `bias` `[Cout]`) as a
/// row-major `[B, Cout, H', W']`: one product per band of output rows, bands in parallel.
pub fn forward(g: &Geometry, x: &[f32], w: &[f32], bias: Option<&[f32]>) -> Vec<f32> {
    let hw_out = g.ho * g.wo;
    let mut out = vec![0f32; g.batch * g.cout * hw_out];
    let dst = SendPtr(out.as_mut_ptr());
    g.for_each_band(bands(g).0, |b, oy0, oy1| {
        // SAFETY: every task writes the pixels of its own rows [oy0, oy1) of its own image,
        // so no two tasks touch the same element, and `out` outlives the loop.
        unsafe { band(g, x, w, bias, b, oy0, oy1, dst) };
    });
    out
}

/// Contiguous groups the weight gradient's bands are summed in: a fixed number, so that the
/// order of the additions (and so every bit of the gradient) is the same on any thread count.
pub const GRAD_GROUPS: usize = 8;

/// `∂L/∂W` `[Cout, Cin·kh·kw]` from the input `x` and the output gradient `grad`
/// `[B, Cout, H', W']`: the bands of output rows (image by image) cut into at most
/// [`GRAD_GROUPS`] contiguous groups, each summed in order on one thread, then the groups'
/// sums added in order. (A rayon fold/reduce would add in an order set by work stealing: the
/// weights after a training step would differ from run to run and between thread counts.)
pub fn weight_grad(g: &Geometry, x: &[f32], grad: &[f32]) -> Vec<f32> {
    let (k, cout) = (g.k(), g.cout);
    let (rows, bands_per_image) = bands(g);
    let tasks = g.batch * bands_per_image;
    let groups = GRAD_GROUPS.min(tasks).max(1);
    let partials: Vec<Vec<f32>> = (0..groups)
        .into_par_iter()
        .map(|group| {
            let mut acc = vec![0f32; cout * k];
            for task in group * tasks / groups..(group + 1) * tasks / groups {
                let (b, band) = (task / bands_per_image, task % bands_per_image);
                let oy0 = band * rows;
                band_weight_grad(g, x, grad, b, oy0, (oy0 + rows).min(g.ho), &mut acc);
            }
            acc
        })
        .collect();
    let mut partials = partials.into_iter();
    let mut total = partials.next().unwrap_or_else(|| vec![0f32; cout * k]);
    for p in partials {
        total.iter_mut().zip(&p).for_each(|(u, v)| *u += v);
    }
    total
}

/// Rows per band and bands per image.
pub fn bands(g: &Geometry) -> (usize, usize) {
    // At least two bands per image, so that one image still feeds two threads.
    let rows = (BAND_FLOATS / (g.k() * g.wo)).clamp(1, g.ho.div_ceil(2).max(1));
    (rows, g.ho.div_ceil(rows))
}

/// A 1×1, stride-1, unpadded convolution reads its input as the patch matrix.
fn is_pointwise(g: &Geometry) -> bool {
    g.kh == 1 && g.kw == 1 && g.stride == [1, 1] && g.pad == [0, 0] && (g.ho, g.wo) == (g.h, g.w)
}

/// Adds `grad(rows [oy0, oy1) of image b) · cols(band)ᵀ` to `acc` `[Cout, k]`.
fn band_weight_grad(
    g: &Geometry,
    x: &[f32],
    grad: &[f32],
    b: usize,
    oy0: usize,
    oy1: usize,
    acc: &mut [f32],
) {
    let (hw_in, hw_out, k) = (g.h * g.w, g.ho * g.wo, g.k());
    let n = (oy1 - oy0) * g.wo;
    let p0 = oy0 * g.wo;
    let image = &x[b * g.cin * hw_in..(b + 1) * g.cin * hw_in];
    let grad = &grad[b * g.cout * hw_out + p0..];
    // rhs = colsᵀ [n, k]: element (p, kk) at rhs[p·rs + kk·cs].
    let product = |rhs: *const f32, rhs_cs: usize, acc: &mut [f32]| unsafe {
        // SAFETY: acc is [Cout, k]; grad rows hold n pixels at stride H'·W'; rhs spans
        // k columns of n pixels at the given strides, inside its slice.
        gemm::gemm(
            g.cout,
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
    with_patches(g, image, oy0, oy1, |cols, stride| {
        product(cols, stride, acc)
    });
}

/// Output rows `[oy0, oy1)` of image `b`.
///
/// # Safety
/// `dst` points at the `[B, Cout, H', W']` output, and no other thread writes these rows.
#[allow(clippy::too_many_arguments)]
unsafe fn band(
    g: &Geometry,
    x: &[f32],
    w: &[f32],
    bias: Option<&[f32]>,
    b: usize,
    oy0: usize,
    oy1: usize,
    dst: SendPtr,
) {
    let (hw_in, hw_out, k) = (g.h * g.w, g.ho * g.wo, g.k());
    let n = (oy1 - oy0) * g.wo;
    let p0 = oy0 * g.wo;
    let image = &x[b * g.cin * hw_in..(b + 1) * g.cin * hw_in];
    // SAFETY (all of the raw pointer uses below): the caller gives this band to this thread
    // alone; offsets stay inside image b's [Cout, H'·W'] block.
    let out = unsafe { dst.0.add(b * g.cout * hw_out + p0) };
    if let Some(bias) = bias {
        for (c, &v) in bias.iter().enumerate().take(g.cout) {
            let row = unsafe { std::slice::from_raw_parts_mut(out.add(c * hw_out), n) };
            row.fill(v);
        }
    }
    let product = |rhs: *const f32, rhs_rs: usize| unsafe {
        gemm::gemm(
            g.cout,
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
    with_patches(g, image, oy0, oy1, product);
}

/// Calls `product(cols, stride)` with the patch matrix `[Cin·kh·kw, n]` of output rows
/// `[oy0, oy1)` of `image`, rows `stride` floats apart: the image itself for a pointwise
/// convolution, else this thread's buffer, unfolded.
fn with_patches<R>(
    g: &Geometry,
    image: &[f32],
    oy0: usize,
    oy1: usize,
    product: impl FnOnce(*const f32, usize) -> R,
) -> R {
    if is_pointwise(g) {
        return product(image[oy0 * g.wo..].as_ptr(), g.h * g.w);
    }
    let (k, n) = (g.k(), (oy1 - oy0) * g.wo);
    PATCHES.with(|cell| {
        let mut cols = cell.borrow_mut();
        if cols.len() < k * n {
            cols.resize(k * n, 0.0);
        }
        unfold(g, image, oy0, oy1, &mut cols[..k * n]);
        product(cols.as_ptr(), n)
    })
}

/// The patch matrix of output rows `[oy0, oy1)`: `cols[(c·kh + ky)·kw + kx][p]` is the input
/// under tap (ky, kx) of channel c for output pixel p of the band, zero outside the image.
///
/// # Shapes
/// `image` `[Cin, H, W]` → `cols` `[Cin·kh·kw, (oy1 − oy0)·W']`
fn unfold(g: &Geometry, image: &[f32], oy0: usize, oy1: usize, cols: &mut [f32]) {
    let n = (oy1 - oy0) * g.wo;
    let [sy, sx] = g.stride;
    let [dy, dx] = g.dilation;
    let [py, px] = g.pad;
    for (row, dst) in cols.chunks_exact_mut(n).enumerate() {
        let (c, tap) = (row / (g.kh * g.kw), row % (g.kh * g.kw));
        let (ky, kx) = (tap / g.kw, tap % g.kw);
        let plane = &image[c * g.h * g.w..(c + 1) * g.h * g.w];
        // Output columns whose input column ox·sx + kx·dx − px lies inside [0, W).
        let shift = (kx * dx) as isize - px as isize;
        let lo = ((-shift).max(0) as usize).div_ceil(sx).min(g.wo);
        let hi = if (g.w as isize) <= shift {
            lo
        } else {
            ((g.w as isize - shift - 1) as usize / sx + 1).clamp(lo, g.wo)
        };
        for (oy, seg) in (oy0..oy1).zip(dst.chunks_exact_mut(g.wo)) {
            let iy = (oy * sy + ky * dy) as isize - py as isize;
            if iy < 0 || iy >= g.h as isize {
                seg.fill(0.0);
                continue;
            }
            let src = &plane[iy as usize * g.w..(iy as usize + 1) * g.w];
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

thread_local! {
    /// Each rayon thread's patch matrix, kept between calls.
    static PATCHES: RefCell<Vec<f32>> = const { RefCell::new(Vec::new()) };
}
