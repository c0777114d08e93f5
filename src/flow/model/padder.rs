//! Inputs of any size: pad to a multiple of 8 (and to the pyramid's minimum) by edge
//! replication, run, and crop the flow back — RAFT's `InputPadder`.

use burn::prelude::*;

/// Padding chosen for one input size: centred vertically and horizontally.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct InputPadder {
    pub height: usize,
    pub width: usize,
    pub top: usize,
    pub bottom: usize,
    pub left: usize,
    pub right: usize,
}

impl InputPadder {
    /// Padding for `[H, W]` so both sides are multiples of 8 and at least `min_side`.
    pub fn new(height: usize, width: usize, min_side: usize) -> Self {
        let target = |n: usize| n.max(min_side).div_ceil(8) * 8;
        let (ph, pw) = (target(height) - height, target(width) - width);
        Self {
            height,
            width,
            top: ph / 2,
            bottom: ph - ph / 2,
            left: pw / 2,
            right: pw - pw / 2,
        }
    }

    pub fn padded_size(&self) -> (usize, usize) {
        (
            self.height + self.top + self.bottom,
            self.width + self.left + self.right,
        )
    }

    /// # Shapes
    /// `[B, C, H, W]` → `[B, C, H', W']`, edges replicated. An edge that gets no padding (one
    /// side of an odd total, or a side already a multiple of 8) adds nothing.
    pub fn pad(&self, x: Tensor<4>) -> Tensor<4> {
        let x = replicate_edges(x, 2, self.top, self.bottom);
        replicate_edges(x, 3, self.left, self.right)
    }

    /// # Shapes
    /// `[B, C, H', W']` → `[B, C, H, W]`
    pub fn unpad(&self, x: Tensor<4>) -> Tensor<4> {
        x.narrow(2, self.top, self.height)
            .narrow(3, self.left, self.width)
    }
}

/// `x` with its first slice along `dim` repeated `before` times in front and its last slice
/// repeated `after` times behind.
fn replicate_edges(x: Tensor<4>, dim: usize, before: usize, after: usize) -> Tensor<4> {
    if before + after == 0 {
        return x;
    }
    let n = x.dims()[dim];
    let edge = |at: usize, times: usize| {
        let slice = x.clone().narrow(dim, at, 1);
        let mut shape = slice.dims();
        shape[dim] = times;
        slice.expand(shape)
    };
    let mut parts = Vec::with_capacity(3);
    if before > 0 {
        parts.push(edge(0, before));
    }
    parts.push(x.clone());
    if after > 0 {
        parts.push(edge(n - 1, after));
    }
    Tensor::cat(parts, dim)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flow::kernels::testing::Tol;
    use crate::flow::ops::testing::assert_tensors_close;

    #[test]
    fn pads_to_multiples_of_eight_and_back() {
        let p = InputPadder::new(37, 50, 64);
        assert_eq!(p.padded_size(), (64, 64));
        let p = InputPadder::new(436, 1024, 64);
        assert_eq!(p.padded_size(), (440, 1024));
        let dev = Device::flex();
        let x = Tensor::<4>::random([1, 2, 37, 50], burn::tensor::Distribution::Default, &dev);
        let p = InputPadder::new(37, 50, 64);
        let y = p.pad(x.clone());
        assert_eq!(y.dims(), [1, 2, 64, 64]);
        assert_tensors_close(p.unpad(y), x, Tol::Abs(0.0), "unpadded");
    }

    /// Every residue mod 8 on both axes, including the ones that pad one edge only (7 mod 8:
    /// one row, all of it at the bottom; KITTI's 375 rows are such a size).
    #[test]
    fn pads_every_residue_with_replicated_edges() {
        let dev = Device::flex();
        for h in 1..=17 {
            for w in [1, 2, 7, 8, 9, 15, 23] {
                let p = InputPadder::new(h, w, 8);
                let (ph, pw) = p.padded_size();
                assert!(ph % 8 == 0 && pw % 8 == 0 && ph >= h && pw >= w, "{h}x{w}");
                let v: Vec<f32> = (0..h * w).map(|i| i as f32).collect();
                let x = Tensor::<4>::from_data(TensorData::new(v, [1, 1, h, w]), &dev);
                let y = p.pad(x.clone());
                assert_eq!(y.dims(), [1, 1, ph, pw], "{h}x{w}");
                let yv: Vec<f32> = y.clone().into_data().try_to_vec::<f32>().unwrap();
                // Corners of the padded map are the image's corners.
                assert_eq!(yv[0], 0.0);
                assert_eq!(yv[ph * pw - 1], (h * w - 1) as f32);
                assert_tensors_close(p.unpad(y), x, Tol::Abs(0.0), &format!("{h}x{w}"));
            }
        }
    }
}
