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

    /// Forward transform of a real grid `[rows, cols]` (row-major) into the transposed half
    /// spectrum `[cols/2 + 1, rows]`.
    pub fn forward(&self, grid: &mut [f32]) -> Vec<Complex32> {
        let (rows, cols, hc) = (self.rows, self.cols, self.half_cols());
        debug_assert_eq!(grid.len(), rows * cols);
        let mut spec_rows = vec![Complex32::new(0.0, 0.0); rows * hc];
        grid.par_chunks_mut(cols)
            .zip(spec_rows.par_chunks_mut(hc))
            .for_each_init(
                || self.r2c.make_scratch_vec(),
                |scratch, (row, out)| {
                    // Lengths match the plan by construction, so this cannot fail.
                    let _ = self.r2c.process_with_scratch(row, out, scratch);
                },
            );
        let mut spec = transpose(&spec_rows, rows, hc);
        spec.par_chunks_mut(rows).for_each_init(
            || vec![Complex32::new(0.0, 0.0); self.col_fwd.get_inplace_scratch_len()],
            |scratch, col| self.col_fwd.process_with_scratch(col, scratch),
        );
        spec
    }

    /// Inverse of [`Fft2::forward`], scaled by `1 / (rows·cols)` so that a round trip is the
    /// identity. Consumes the spectrum; writes the real grid `[rows, cols]`.
    pub fn inverse(&self, mut spec: Vec<Complex32>, grid: &mut [f32]) {
        let (rows, cols, hc) = (self.rows, self.cols, self.half_cols());
        spec.par_chunks_mut(rows).for_each_init(
            || vec![Complex32::new(0.0, 0.0); self.col_inv.get_inplace_scratch_len()],
            |scratch, col| self.col_inv.process_with_scratch(col, scratch),
        );
        let mut spec_rows = transpose(&spec, hc, rows);
        let scale = 1.0 / (rows * cols) as f32;
        grid.par_chunks_mut(cols)
            .zip(spec_rows.par_chunks_mut(hc))
            .for_each_init(
                || self.c2r.make_scratch_vec(),
                |scratch, (row, input)| {
                    // The imaginary parts of the DC and Nyquist bins are rounding noise for a
                    // real signal's spectrum; realfft rejects them unless they are zero.
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

/// Transposes a row-major `[rows, cols]` buffer into `[cols, rows]`, in cache-sized tiles.
fn transpose(src: &[Complex32], rows: usize, cols: usize) -> Vec<Complex32> {
    const TILE: usize = 32;
    let mut dst = vec![Complex32::new(0.0, 0.0); rows * cols];
    dst.par_chunks_mut(TILE * rows)
        .enumerate()
        .for_each(|(tile, block)| {
            let c0 = tile * TILE;
            let c1 = (c0 + TILE).min(cols);
            for r0 in (0..rows).step_by(TILE) {
                for r in r0..(r0 + TILE).min(rows) {
                    let src_row = &src[r * cols..];
                    for c in c0..c1 {
                        block[(c - c0) * rows + r] = src_row[c];
                    }
                }
            }
        });
    dst
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
    }
}
