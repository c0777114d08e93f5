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
    /// `[B, C, H, W]` → `[B, C, H', W']`, edges replicated.
    pub fn pad(&self, x: Tensor<4>) -> Tensor<4> {
        let mut x = x;
        let [b, c, h, w] = x.dims();
        if self.top + self.bottom > 0 {
            let first = x.clone().narrow(2, 0, 1).expand([b, c, self.top, w]);
            let last = x.clone().narrow(2, h - 1, 1).expand([b, c, self.bottom, w]);
            x = Tensor::cat(vec![first, x, last], 2);
        }
        let h = h + self.top + self.bottom;
        if self.left + self.right > 0 {
            let first = x.clone().narrow(3, 0, 1).expand([b, c, h, self.left]);
            let last = x.clone().narrow(3, w - 1, 1).expand([b, c, h, self.right]);
            x = Tensor::cat(vec![first, x, last], 3);
        }
        x
    }

    /// # Shapes
    /// `[B, C, H', W']` → `[B, C, H, W]`
    pub fn unpad(&self, x: Tensor<4>) -> Tensor<4> {
        x.narrow(2, self.top, self.height)
            .narrow(3, self.left, self.width)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
        let back = p.unpad(y);
        let d: f32 = (back - x).abs().max().into_scalar();
        assert_eq!(d, 0.0);
    }
}
