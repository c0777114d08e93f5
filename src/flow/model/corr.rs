//! All-pairs correlation (Note S9): the dot products of every 1/8-resolution feature of frame 1
//! with every one of frame 2, scaled by 1/√C, `C[p, q] = f1(p) · f2(q) / √C`, average-pooled
//! 2×2 into a pyramid of `levels` levels, and looked up in a (2r+1)² window around x + F(x) at
//! every level l (positions scaled by 2^−l) by bilinear interpolation, zero outside the level.
//! The two operations are [`ops::corr_pyramid`] and [`ops::corr_lookup`].

use burn::prelude::*;

use crate::flow::ops;

/// The correlation pyramid of one image pair and the lookup radius r.
pub struct CorrPyramid {
    pyramid: ops::Pyramid,
    radius: usize,
}

impl CorrPyramid {
    /// # Shapes
    /// `f1`, `f2`: `[B, C, H, W]` → levels `[B·H·W, H/2^l, W/2^l]`
    pub fn new(f1: Tensor<4>, f2: Tensor<4>, num_levels: usize, radius: usize) -> Self {
        Self {
            pyramid: ops::corr_pyramid(f1, f2, num_levels),
            radius,
        }
    }

    /// Looks up every level around `coords`, the (x, y) position in frame 2 of every pixel.
    ///
    /// # Shapes
    /// `coords`: `[B, 2, H, W]` → `[B, levels·(2r+1)², H, W]`
    pub fn lookup(&self, coords: Tensor<4>) -> Tensor<4> {
        ops::corr_lookup(&self.pyramid, coords, self.radius)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flow::kernels::testing::{Tol, assert_close};

    #[test]
    fn lookup_at_integer_coords_reads_the_correlation() {
        let dev = Device::flex();
        // B=1, C=1, H=W=4: f1 = 1 everywhere, f2 = x index, so corr(p, q) = q.x.
        let f1 = Tensor::<4>::ones([1, 1, 4, 4], &dev);
        let f2 = Tensor::<1, Int>::arange(0..4, &dev)
            .float()
            .reshape([1, 1, 1, 4])
            .expand([1, 1, 4, 4]);
        let pyr = CorrPyramid::new(f1, f2, 2, 1);
        // Every pixel looks at (x, y) = (1.5, 1): half-way between columns 1 and 2.
        let coords = Tensor::<4>::zeros([1, 2, 4, 4], &dev)
            + Tensor::<1>::from_floats([1.5, 1.0], &dev).reshape([1, 2, 1, 1]);
        let out = pyr.lookup(coords); // [1, 2·9, 4, 4]
        assert_eq!(out.dims(), [1, 18, 4, 4]);
        let v: Vec<f32> = out
            .slice([0..1, 0..9, 0..1, 0..1])
            .into_data()
            .try_to_vec::<f32>()
            .unwrap();
        // Window row dy = 0 (index 3..6) samples x = 0.5, 1.5, 2.5.
        assert_close(
            &v[3..6],
            &[0.5, 1.5, 2.5],
            Tol::Abs(1e-5),
            "window row dy = 0",
        );
        // Far outside: zero padding, finite.
        let far = Tensor::<4>::zeros([1, 2, 4, 4], &dev).add_scalar(1e4);
        let o: Vec<f32> = pyr.lookup(far).into_data().try_to_vec::<f32>().unwrap();
        assert!(o.iter().all(|x| *x == 0.0));
    }
}
