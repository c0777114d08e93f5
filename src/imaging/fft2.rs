//! Two-dimensional real FFT on a fixed grid: rows by real-to-complex transforms, columns by
//! complex transforms on a transposed buffer, so every 1-D transform runs on contiguous memory.

use std::sync::Arc;

use rayon::prelude::*;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use rustfft::{Fft, FftPlanner, num_complex::Complex32};

/// Plans for one `[rows, cols]` real grid. The spectrum is stored transposed,
/// `[cols / 2 + 1, rows]`, which is the layout the column transforms need.
pub struct Fft2 {
    rows: usize,
    cols: usize,
    r2c: Arc<dyn RealToComplex<f32>>,
    c2r: Arc<dyn ComplexToReal<f32>>,
    col_fwd: Arc<dyn Fft<f32>>,
    col_inv: Arc<dyn Fft<f32>>,
}

impl Fft2 {
    /// Plans transforms for a `rows × cols` real grid.
    pub fn new(rows: usize, cols: usize) -> Self {
        let mut real = RealFftPlanner::<f32>::new();
        let mut complex = FftPlanner::<f32>::new();
        Self {
            rows,
            cols,
            r2c: real.plan_fft_forward(cols),
            c2r: real.plan_fft_inverse(cols),
            col_fwd: complex.plan_fft_forward(rows),
            col_inv: complex.plan_fft_inverse(rows),
        }
    }

    pub fn rows(&self) -> usize {
        self.rows
    }
    pub fn cols(&self) -> usize {
        self.cols
    }
    /// Number of complex columns of the half spectrum.
    pub fn half_cols(&self) -> usize {
        self.cols / 2 + 1
    }

    /// Working memory for [`Fft2::filter_into`], reused across calls (fresh buffers of this
    /// size would cost a page fault per 4 KiB on every frame).
    pub fn scratch(&self) -> Fft2Scratch {
        let n = self.rows * self.half_cols();
        Fft2Scratch {
            spec_rows: vec![Complex32::new(0.0, 0.0); n],
            spec: vec![Complex32::new(0.0, 0.0); n],
        }
    }

    /// Row transforms of `grid` (rows at and beyond `filled` are zero and skipped), then the
    /// transpose into `s.spec` `[cols/2 + 1, rows]`.
    fn rows_forward(&self, grid: &mut [f32], filled: usize, s: &mut Fft2Scratch) {
        let (rows, cols, hc) = (self.rows, self.cols, self.half_cols());
        debug_assert_eq!(grid.len(), rows * cols);
        let filled = filled.min(rows);
        grid[..filled * cols]
            .par_chunks_mut(cols)
            .zip(s.spec_rows[..filled * hc].par_chunks_mut(hc))
            .for_each_init(
                || self.r2c.make_scratch_vec(),
                |scratch, (row, out)| {
                    // Lengths match the plan by construction, so this cannot fail.
                    let _ = self.r2c.process_with_scratch(row, out, scratch);
                },
            );
        s.spec_rows[filled * hc..].fill(Complex32::new(0.0, 0.0));
        transpose_into(&s.spec_rows, rows, hc, &mut s.spec);
    }

    /// Forward transform of a real grid `[rows, cols]` (row-major) into the transposed half
    /// spectrum `[cols/2 + 1, rows]`.
    pub fn forward(&self, grid: &mut [f32]) -> Vec<Complex32> {
        let mut s = self.scratch();
        self.rows_forward(grid, self.rows, &mut s);
        s.spec.par_chunks_mut(self.rows).for_each_init(
            || vec![Complex32::new(0.0, 0.0); self.col_fwd.get_inplace_scratch_len()],
            |scratch, col| self.col_fwd.process_with_scratch(col, scratch),
        );
        s.spec
    }

    /// Circular convolution of `grid` with the filter whose spectrum (from [`Fft2::forward`])
    /// is `kernel`, keeping only output rows `r0..r0 + h` and columns `c0..c0 + w`, times
    /// `gain`, written to `out` `[h, w]`. Each column is transformed, filtered and transformed
    /// back while it is in cache, and only the rows kept are transformed back.
    #[allow(clippy::too_many_arguments)]
    pub fn filter_into(
        &self,
        grid: &mut [f32],
        filled: usize,
        kernel: &[Complex32],
        s: &mut Fft2Scratch,
        (r0, h): (usize, usize),
        (c0, w): (usize, usize),
        gain: f32,
        out: &mut [f32],
    ) {
        let (rows, cols, hc) = (self.rows, self.cols, self.half_cols());
        debug_assert!(r0 + h <= rows && c0 + w <= cols && out.len() == h * w);
        self.rows_forward(grid, filled, s);
        let (fwd, inv) = (&self.col_fwd, &self.col_inv);
        let len = fwd
            .get_inplace_scratch_len()
            .max(inv.get_inplace_scratch_len());
        s.spec
            .par_chunks_mut(rows)
            .zip(kernel.par_chunks(rows))
            .for_each_init(
                || vec![Complex32::new(0.0, 0.0); len],
                |scratch, (col, k)| {
                    fwd.process_with_scratch(col, scratch);
                    col.iter_mut().zip(k).for_each(|(a, b)| *a *= b);
                    inv.process_with_scratch(col, scratch);
                },
            );
        // Only rows r0..r0 + h come back: transpose them, then one inverse real FFT each.
        transpose_rows_into(&s.spec, hc, rows, r0, h, &mut s.spec_rows[..h * hc]);
        let scale = gain / (rows * cols) as f32;
        out.par_chunks_mut(w)
            .zip(s.spec_rows[..h * hc].par_chunks_mut(hc))
            .for_each_init(
                || (self.c2r.make_scratch_vec(), vec![0.0f32; cols]),
                |(scratch, line), (row, input)| {
                    // The imaginary parts of the DC and Nyquist bins are rounding noise for a
                    // real signal's spectrum; realfft rejects them unless they are zero.
                    input[0].im = 0.0;
                    if cols % 2 == 0 {
                        input[hc - 1].im = 0.0;
                    }
                    let _ = self.c2r.process_with_scratch(input, line, scratch);
                    for (o, &v) in row.iter_mut().zip(&line[c0..c0 + w]) {
                        *o = v * scale;
                    }
                },
            );
    }

    /// Inverse of [`Fft2::forward`], scaled by `1 / (rows·cols)` so that a round trip is the
    /// identity. Consumes the spectrum; writes the real grid `[rows, cols]`.
    pub fn inverse(&self, mut spec: Vec<Complex32>, grid: &mut [f32]) {
        let (rows, cols, hc) = (self.rows, self.cols, self.half_cols());
        spec.par_chunks_mut(rows).for_each_init(
            || vec![Complex32::new(0.0, 0.0); self.col_inv.get_inplace_scratch_len()],
            |scratch, col| self.col_inv.process_with_scratch(col, scratch),
        );
        let mut spec_rows = vec![Complex32::new(0.0, 0.0); rows * hc];
        transpose_into(&spec, hc, rows, &mut spec_rows);
        let scale = 1.0 / (rows * cols) as f32;
        grid.par_chunks_mut(cols)
            .zip(spec_rows.par_chunks_mut(hc))
            .for_each_init(
                || self.c2r.make_scratch_vec(),
                |scratch, (row, input)| {
                    input[0].im = 0.0;
                    if cols % 2 == 0 {
                        input[hc - 1].im = 0.0;
                    }
                    let _ = self.c2r.process_with_scratch(input, row, scratch);
                    row.iter_mut().for_each(|v| *v *= scale);
                },
            );
    }
}

/// Reusable buffers of one [`Fft2`] (see [`Fft2::scratch`]).
pub struct Fft2Scratch {
    spec_rows: Vec<Complex32>,
    spec: Vec<Complex32>,
}

/// Transposes a row-major `[rows, cols]` buffer into `dst` `[cols, rows]`, in cache-sized tiles.
fn transpose_into(src: &[Complex32], rows: usize, cols: usize, dst: &mut [Complex32]) {
    transpose_rows_into(src, rows, cols, 0, cols, dst);
}

/// Columns `c0..c0 + n` of the row-major `[rows, cols]` buffer `src`, transposed into `dst`
/// `[n, rows]`, in cache-sized tiles.
fn transpose_rows_into(
    src: &[Complex32],
    rows: usize,
    cols: usize,
    c0: usize,
    n: usize,
    dst: &mut [Complex32],
) {
    const TILE: usize = 32;
    debug_assert!(c0 + n <= cols && dst.len() >= n * rows);
    dst[..n * rows]
        .par_chunks_mut(TILE * rows)
        .enumerate()
        .for_each(|(tile, block)| {
            let a = c0 + tile * TILE;
            let b = (a + TILE).min(c0 + n);
            for r0 in (0..rows).step_by(TILE) {
                for r in r0..(r0 + TILE).min(rows) {
                    let src_row = &src[r * cols..];
                    for c in a..b {
                        block[(c - a) * rows + r] = src_row[c];
                    }
                }
            }
        });
}

/// The smallest `n' ≥ n` whose only prime factors are 2, 3 and 5 (and even, for real FFTs).
pub fn next_fast_len(n: usize) -> usize {
    let mut m = n.max(2);
    loop {
        if m.is_multiple_of(2) {
            let mut k = m;
            for p in [2, 3, 5] {
                while k.is_multiple_of(p) {
                    k /= p;
                }
            }
            if k == 1 {
                return m;
            }
        }
        m += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_lengths() {
        assert_eq!(next_fast_len(1), 2);
        assert_eq!(next_fast_len(97), 100);
        assert_eq!(next_fast_len(511), 512);
        assert_eq!(next_fast_len(1441 + 64), 1536);
    }

    #[test]
    fn round_trip_is_identity() {
        let (r, c) = (30, 50);
        let fft = Fft2::new(r, c);
        let orig: Vec<f32> = (0..r * c)
            .map(|i| ((i * 7919) % 101) as f32 / 101.0)
            .collect();
        let mut grid = orig.clone();
        let spec = fft.forward(&mut grid);
        assert_eq!(spec.len(), (c / 2 + 1) * r);
        let mut back = vec![0.0; r * c];
        fft.inverse(spec, &mut back);
        for (a, b) in orig.iter().zip(&back) {
            assert!((a - b).abs() < 1e-5, "{a} vs {b}");
        }
        // Filtering by a unit impulse at (0, 0) with a window and a gain is a scaled crop.
        let mut impulse = vec![0.0f32; r * c];
        impulse[0] = 1.0;
        let k = fft.forward(&mut impulse);
        let mut s = fft.scratch();
        let mut grid = orig.clone();
        let mut out = vec![0.0f32; 7 * 11];
        fft.filter_into(&mut grid, r, &k, &mut s, (5, 7), (3, 11), 2.0, &mut out);
        for y in 0..7 {
            for x in 0..11 {
                let want = 2.0 * orig[(y + 5) * c + x + 3];
                assert!((out[y * 11 + x] - want).abs() < 1e-5);
            }
        }
    }
}
