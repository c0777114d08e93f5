//! PSF convolution of a planar image (the blur of Note S4's PSF-based imaging), with mirrored
//! borders, by direct summation for small kernels and by FFT for large ones, chosen by cost.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use std::sync::Mutex;

use super::fft2::{Fft2, Fft2Scratch, next_fast_len};

/// How a convolution is computed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ConvMethod {
    /// Whichever of the two the cost model predicts to be faster.
    #[default]
    Auto,
    /// Direct summation over the kernel: `H·W·h·w` multiply-adds.
    Direct,
    /// FFT on a grid of at least `(H + h − 1) × (W + w − 1)`.
    Fft,
}

/// Relative cost of one FFT "butterfly unit" (`M·N·log2(M·N)`) against one direct multiply-add,
/// measured on this project's benchmark (`pins bench`): the direct inner loop is a vectorised
/// axpy, the FFT a forward and an inverse pass over the padded grid.
const FFT_UNIT_COST: f64 = 2.5;

/// Chooses Direct or FFT for an `h × w` kernel on an `height × width` plane.
pub fn choose_method(height: usize, width: usize, kh: usize, kw: usize) -> ConvMethod {
    let direct = (height * width) as f64 * (kh * kw) as f64;
    let (m, n) = fft_grid(height, width, kh, kw);
    let mn = (m * n) as f64;
    let fft = FFT_UNIT_COST * mn * mn.log2();
    if direct <= fft {
        ConvMethod::Direct
    } else {
        ConvMethod::Fft
    }
}

/// The FFT grid for an `h × w` kernel on an `height × width` plane with mirrored borders.
pub fn fft_grid(height: usize, width: usize, kh: usize, kw: usize) -> (usize, usize) {
    (
        next_fast_len(height + kh - 1),
        next_fast_len(width + kw - 1),
    )
}

/// Index into `0..n` of position `i` under mirror reflection without repeating the edge
/// sample (OpenCV's BORDER_REFLECT_101), valid for any offset, however far outside.
#[inline]
pub fn mirror(i: isize, n: usize) -> usize {
    if n == 1 {
        return 0;
    }
    let period = 2 * (n as isize - 1);
    let m = i.rem_euclid(period);
    if m >= n as isize {
        (period - m) as usize
    } else {
        m as usize
    }
}

/// The plane `[height, width]` padded by `(ry, rx)` on every side with mirrored samples.
pub fn pad_mirror(plane: &[f32], height: usize, width: usize, ry: usize, rx: usize) -> Vec<f32> {
    let wp = width + 2 * rx;
    let mut out = vec![0.0f32; (height + 2 * ry) * wp];
    pad_mirror_into(plane, height, width, ry, rx, &mut out, wp);
    out
}

/// Writes the mirrored padding of `plane` into the first `height + 2·ry` rows of `out`, whose
/// rows are `stride` long (at least `width + 2·rx`), leaving the rest of `out` untouched.
pub fn pad_mirror_into(
    plane: &[f32],
    height: usize,
    width: usize,
    ry: usize,
    rx: usize,
    out: &mut [f32],
    stride: usize,
) {
    let (hp, wp) = (height + 2 * ry, width + 2 * rx);
    let cols: Vec<usize> = (0..wp)
        .map(|x| mirror(x as isize - rx as isize, width))
        .collect();
    out.par_chunks_mut(stride)
        .take(hp)
        .enumerate()
        .for_each(|(y, row)| {
            let src = &plane[mirror(y as isize - ry as isize, height) * width..][..width];
            row[rx..rx + width].copy_from_slice(src);
            for x in (0..rx).chain(rx + width..wp) {
                row[x] = src[cols[x]];
            }
        });
}

/// Direct convolution of `plane` `[height, width]` with the odd kernel `[kh, kw]`, mirrored
/// borders, output `[height, width]`.
pub fn convolve_direct(
    plane: &[f32],
    height: usize,
    width: usize,
    kernel: &[f32],
    kh: usize,
    kw: usize,
) -> Vec<f32> {
    let padded = pad_mirror(plane, height, width, kh / 2, kw / 2);
    let wp = width + kw - 1;
    let mut out = vec![0.0f32; height * width];
    out.par_chunks_mut(width)
        .enumerate()
        .for_each(|(y, out_row)| {
            for i in 0..kh {
                let src_row = &padded[(y + kh - 1 - i) * wp..][..wp];
                let krow = &kernel[i * kw..][..kw];
                for (j, &k) in krow.iter().enumerate() {
                    if k == 0.0 {
                        continue;
                    }
                    let src = &src_row[kw - 1 - j..][..width];
                    for (o, &s) in out_row.iter_mut().zip(src) {
                        *o += k * s;
                    }
                }
            }
        });
    out
}

/// A kernel prepared for FFT convolution of planes of one size: the plans and the kernel's
/// spectrum, computed once and reused for every frame of that size.
pub struct FftConvolver {
    height: usize,
    width: usize,
    kh: usize,
    kw: usize,
    fft: Fft2,
    kernel_spectrum: Vec<rustfft::num_complex::Complex32>,
    /// Grids and spectra of earlier calls, reused so frames after the first allocate nothing.
    pool: Mutex<Vec<(Vec<f32>, Fft2Scratch)>>,
}

impl FftConvolver {
    /// Prepares `kernel` (`kh × kw`, row-major) for planes of `height × width`.
    pub fn new(kernel: &[f32], kh: usize, kw: usize, height: usize, width: usize) -> Self {
        let (m, n) = fft_grid(height, width, kh, kw);
        let fft = Fft2::new(m, n);
        let mut grid = vec![0.0f32; m * n];
        for i in 0..kh {
            grid[i * n..i * n + kw].copy_from_slice(&kernel[i * kw..(i + 1) * kw]);
        }
        let kernel_spectrum = fft.forward(&mut grid);
        Self {
            height,
            width,
            kh,
            kw,
            fft,
            kernel_spectrum,
            pool: Mutex::new(Vec::new()),
        }
    }

    /// Convolves one `height × width` plane (mirror boundary), same size out.
    pub fn convolve(&self, plane: &[f32]) -> Vec<f32> {
        let mut out = vec![0.0f32; self.height * self.width];
        self.convolve_into(plane, 1.0, &mut out);
        out
    }

    /// Convolves one plane times `gain` into `out` (`height × width`).
    pub fn convolve_into(&self, plane: &[f32], gain: f32, out: &mut [f32]) {
        let (h, w, kh, kw) = (self.height, self.width, self.kh, self.kw);
        let (m, n) = (self.fft.rows(), self.fft.cols());
        // A poisoned lock only means another thread panicked; the buffers are still valid.
        let taken = self.pool.lock().unwrap_or_else(|e| e.into_inner()).pop();
        let (mut grid, mut scratch) =
            taken.unwrap_or_else(|| (vec![0.0f32; m * n], self.fft.scratch()));
        let filled = h + kh - 1;
        pad_mirror_into(plane, h, w, kh / 2, kw / 2, &mut grid, n);
        // The real transforms overwrite their input, so the zero margin is restored each time.
        let wp = w + kw - 1;
        grid[..filled * n]
            .par_chunks_mut(n)
            .for_each(|row| row[wp..].fill(0.0));
        self.fft.filter_into(
            &mut grid,
            filled,
            &self.kernel_spectrum,
            &mut scratch,
            (kh - 1, h),
            (kw - 1, w),
            gain,
            out,
        );
        self.pool
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push((grid, scratch));
    }
}

/// Convolves one plane with one kernel by `method` (Auto resolved by [`choose_method`]).
pub fn convolve_plane(
    plane: &[f32],
    height: usize,
    width: usize,
    kernel: &[f32],
    kh: usize,
    kw: usize,
    method: ConvMethod,
) -> Vec<f32> {
    let method = match method {
        ConvMethod::Auto => choose_method(height, width, kh, kw),
        m => m,
    };
    match method {
        ConvMethod::Fft => FftConvolver::new(kernel, kh, kw, height, width).convolve(plane),
        _ => convolve_direct(plane, height, width, kernel, kh, kw),
    }
}

/// Reference convolution in f64 with mirrored borders: slow, for tests and benchmarks.
pub fn convolve_reference(
    plane: &[f32],
    height: usize,
    width: usize,
    kernel: &[f32],
    kh: usize,
    kw: usize,
) -> Vec<f64> {
    let (ry, rx) = ((kh / 2) as isize, (kw / 2) as isize);
    let mut out = vec![0.0f64; height * width];
    out.par_chunks_mut(width).enumerate().for_each(|(y, row)| {
        for (x, o) in row.iter_mut().enumerate() {
            let mut acc = 0.0f64;
            for i in 0..kh {
                let sy = mirror(y as isize + ry - i as isize, height);
                for j in 0..kw {
                    let sx = mirror(x as isize + rx - j as isize, width);
                    acc += kernel[i * kw + j] as f64 * plane[sy * width + sx] as f64;
                }
            }
            *o = acc;
        }
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn test_plane(h: usize, w: usize) -> Vec<f32> {
        (0..h * w)
            .map(|i| (((i * 2654435761usize) >> 7) % 1000) as f32 / 1000.0)
            .collect()
    }

    fn test_kernel(k: usize) -> Vec<f32> {
        let mut v: Vec<f32> = (0..k * k)
            .map(|i| ((i * 37 + 11) % 17) as f32 + 1.0)
            .collect();
        let s: f32 = v.iter().sum();
        v.iter_mut().for_each(|x| *x /= s);
        v
    }

    #[test]
    fn mirror_reflects_without_repeating_edges() {
        let idx: Vec<usize> = (-3..8).map(|i| mirror(i, 5)).collect();
        assert_eq!(idx, vec![3, 2, 1, 0, 1, 2, 3, 4, 3, 2, 1]);
        assert_eq!(mirror(-100, 1), 0);
        assert!((-50..60).all(|i| mirror(i, 3) < 3));
    }

    #[test]
    fn direct_and_fft_agree_with_f64_reference() {
        for &(h, w, k) in &[(23, 31, 3), (40, 37, 9), (16, 20, 33), (12, 9, 15)] {
            let plane = test_plane(h, w);
            let kern = test_kernel(k);
            let reference = convolve_reference(&plane, h, w, &kern, k, k);
            let d = convolve_direct(&plane, h, w, &kern, k, k);
            let f = FftConvolver::new(&kern, k, k, h, w).convolve(&plane);
            for i in 0..h * w {
                assert!(
                    (d[i] as f64 - reference[i]).abs() < 1e-5,
                    "direct {h}x{w} k{k}"
                );
                assert!(
                    (f[i] as f64 - reference[i]).abs() < 1e-5,
                    "fft {h}x{w} k{k}"
                );
            }
        }
    }

    #[test]
    fn delta_kernel_and_constant_image_are_preserved() {
        let plane = test_plane(10, 13);
        let mut delta = vec![0.0; 25];
        delta[12] = 1.0;
        assert_eq!(convolve_direct(&plane, 10, 13, &delta, 5, 5), plane);
        // A kernel larger than the image still sees a mirrored, constant world.
        let flat = vec![0.7f32; 6 * 5];
        let out = FftConvolver::new(&test_kernel(21), 21, 21, 6, 5).convolve(&flat);
        assert!(out.iter().all(|v| (v - 0.7).abs() < 1e-5));
    }

    #[test]
    fn convolution_is_not_correlation() {
        // An asymmetric kernel with its mass right of centre moves a point to the right.
        let mut plane = vec![0.0f32; 9 * 9];
        plane[4 * 9 + 4] = 1.0;
        let kern = vec![0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0];
        for m in [ConvMethod::Direct, ConvMethod::Fft] {
            let out = convolve_plane(&plane, 9, 9, &kern, 3, 3, m);
            assert!((out[4 * 9 + 5] - 1.0).abs() < 1e-6, "{m:?}");
        }
    }

    #[test]
    fn cost_model_prefers_direct_for_small_kernels() {
        assert_eq!(choose_method(384, 512, 3, 3), ConvMethod::Direct);
        assert_eq!(choose_method(384, 512, 65, 65), ConvMethod::Fft);
    }
}
