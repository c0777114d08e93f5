//! The machine's single-precision matrix product rate: one square `gemm` product `C = A·B`, on
//! one thread or on the kernels' thread pool, for `pins bench-flow --mode kernels` to set every
//! layer's rate against.

/// `c ← a·b` for square row-major `n×n` matrices, on `threads` threads of the pool (1: the
/// calling thread alone).
///
/// # Shapes
/// `a`, `b`, `c`: `[n, n]`
pub fn square_product(a: &[f32], b: &[f32], c: &mut [f32], n: usize, threads: usize) {
    assert!(
        a.len() >= n * n && b.len() >= n * n && c.len() >= n * n,
        "square_product: buffers shorter than {n}×{n}"
    );
    let parallelism = if threads > 1 {
        gemm::Parallelism::Rayon(threads)
    } else {
        gemm::Parallelism::None
    };
    // SAFETY: all three are row-major [n, n] (column stride 1, row stride n), inside their
    // slices by the check above; c does not alias a or b (a `&mut` borrow).
    unsafe {
        gemm::gemm(
            n,
            n,
            n,
            c.as_mut_ptr(),
            1,
            n as isize,
            false,
            a.as_ptr(),
            1,
            n as isize,
            b.as_ptr(),
            1,
            n as isize,
            0.0f32,
            1.0f32,
            false,
            false,
            false,
            parallelism,
        )
    };
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flow::kernels::testing::{Tol, assert_close, cases, values};

    /// The product on one thread and on two equals the definition.
    #[test]
    fn square_product_is_the_matrix_product() {
        let n = 37;
        let mut r = cases("square product", 0);
        let (a, b) = (values(&mut r, n * n, 1.0), values(&mut r, n * n, 1.0));
        let mut want = vec![0f32; n * n];
        for i in 0..n {
            for j in 0..n {
                want[i * n + j] = (0..n).map(|k| a[i * n + k] * b[k * n + j]).sum();
            }
        }
        for threads in [1, 2] {
            let mut c = vec![f32::NAN; n * n];
            square_product(&a, &b, &mut c, n, threads);
            assert_close(&c, &want, Tol::Scaled(1e-5), &format!("{threads} threads"));
        }
    }
}
