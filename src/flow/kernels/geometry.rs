//! The sizes of one 2-D convolution (the 1×1, 3×3 and 7×7 layers of Notes S9–S10, strides 1 and
//! 2, dilations up to 18): input, kernel, stride, padding, dilation and the output they give, and
//! the parallel loop over bands of output rows that the convolution kernels share.

use rayon::prelude::*;

/// Stride, per-side padding and dilation of an ungrouped convolution: the host kernels' copy of
/// Burn's `ConvOptions<2>`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ConvParams {
    pub stride: [usize; 2],
    /// `[(top, bottom), (left, right)]`
    pub padding: [(usize, usize); 2],
    pub dilation: [usize; 2],
}

impl ConvParams {
    /// Stride 1, `pad` on every side, dilation `dil`.
    pub fn same(pad: usize, dil: usize) -> Self {
        Self {
            stride: [1, 1],
            padding: [(pad, pad), (pad, pad)],
            dilation: [dil, dil],
        }
    }
}

/// Sizes of one convolution of `x` `[B, Cin, H, W]` by `w` `[Cout, Cin, kh, kw]` into
/// `[B, Cout, H', W']`.
#[derive(Clone, Copy, Debug)]
pub struct Geometry {
    pub batch: usize,
    pub cin: usize,
    pub h: usize,
    pub w: usize,
    pub cout: usize,
    pub kh: usize,
    pub kw: usize,
    pub stride: [usize; 2],
    /// (top, left)
    pub pad: [usize; 2],
    pub dilation: [usize; 2],
    pub ho: usize,
    pub wo: usize,
}

impl Geometry {
    pub fn new(
        [batch, cin, h, w]: [usize; 4],
        [cout, _, kh, kw]: [usize; 4],
        p: &ConvParams,
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
            stride: p.stride,
            pad: [p.padding[0].0, p.padding[1].0],
            dilation: p.dilation,
            ho: out(h, p.padding[0], kh, p.stride[0], p.dilation[0]),
            wo: out(w, p.padding[1], kw, p.stride[1], p.dilation[1]),
        }
    }

    /// `[B, Cout, H', W']`
    pub fn out_shape(&self) -> [usize; 4] {
        [self.batch, self.cout, self.ho, self.wo]
    }

    /// Patch length: one column of the unfolded input, `Cin·kh·kw`.
    pub fn k(&self) -> usize {
        self.cin * self.kh * self.kw
    }

    /// Runs `f(b, oy0, oy1)` for every band of `rows` output rows `[oy0, oy1)` of every image
    /// `b`, in parallel.
    pub fn for_each_band(&self, rows: usize, f: impl Fn(usize, usize, usize) + Sync) {
        let bands = self.ho.div_ceil(rows);
        (0..self.batch * bands).into_par_iter().for_each(|task| {
            let (b, oy0) = (task / bands, (task % bands) * rows);
            f(b, oy0, (oy0 + rows).min(self.ho));
        });
    }
}

/// The output pointer, shared by the band tasks, each of which writes its own rows.
#[derive(Clone, Copy)]
pub struct SendPtr(pub *mut f32);
// SAFETY: the tasks that share it write disjoint rows (see `unfold::forward` and
// `shifted::forward`).
unsafe impl Send for SendPtr {}
unsafe impl Sync for SendPtr {}

impl SendPtr {
    /// The pointer; a method, so that closures capture the `Send` wrapper, not its field.
    pub fn ptr(self) -> *mut f32 {
        self.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Output sizes follow `(size + p0 + p1 − d·(k − 1) − 1) / s + 1`, and are 0 for a kernel
    /// reaching past the padded input.
    #[test]
    fn output_sizes() {
        let p = ConvParams {
            stride: [2, 1],
            padding: [(1, 0), (2, 2)],
            dilation: [1, 3],
        };
        let g = Geometry::new([2, 4, 9, 10], [5, 4, 3, 3], &p);
        assert_eq!(g.out_shape(), [2, 5, 4, 8]);
        assert_eq!(g.k(), 36);
        let none = Geometry::new([1, 1, 2, 2], [1, 1, 7, 7], &ConvParams::same(0, 1));
        assert_eq!((none.ho, none.wo), (0, 0));
    }
}
