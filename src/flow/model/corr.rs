//! All-pairs correlation (Note S9): the dot products of every 1/8-resolution feature of frame 1
//! with every one of frame 2, scaled by 1/√C, pooled into a pyramid, and looked up in a
//! (2r+1)² window around x + F(x) at every level by bilinear interpolation.

use burn::prelude::*;
use burn::tensor::module::avg_pool2d;
use burn::tensor::ops::AvgPoolOptions;

/// The correlation pyramid of one image pair.
pub struct CorrPyramid {
    /// Level l: `[B·H·W, 1, H/2^l, W/2^l]`.
    levels: Vec<Tensor<3>>,
    sizes: Vec<(usize, usize)>,
    batch: usize,
    height: usize,
    width: usize,
    radius: usize,
}

impl CorrPyramid {
    /// # Shapes
    /// `f1`, `f2`: `[B, C, H, W]` → levels `[B·H·W, h_l, w_l]`
    pub fn new(f1: Tensor<4>, f2: Tensor<4>, num_levels: usize, radius: usize) -> Self {
        let [b, c, h, w] = f1.dims();
        let corr = f1
            .reshape([b, c, h * w])
            .swap_dims(1, 2)
            .matmul(f2.reshape([b, c, h * w])) // [B, HW, HW]
            .div_scalar((c as f32).sqrt())
            .reshape([b * h * w, 1, h, w]);
        let mut levels = Vec::with_capacity(num_levels);
        let mut sizes = Vec::with_capacity(num_levels);
        let mut cur = corr;
        for l in 0..num_levels {
            let [n, _, hl, wl] = cur.dims();
            sizes.push((hl, wl));
            levels.push(cur.clone().reshape([n, hl, wl]));
            if l + 1 < num_levels {
                // A level already 1 cell wide cannot be halved; keep it (the coordinates still
                // scale, so the lookup then sees mostly zero padding, as RAFT's does).
                let k = [2.min(hl), 2.min(wl)];
                cur = avg_pool2d(cur, AvgPoolOptions::new(k).with_stride(k));
            }
        }
        Self {
            levels,
            sizes,
            batch: b,
            height: h,
            width: w,
            radius,
        }
    }

    /// Looks up every level around `coords`, the (x, y) position in frame 2 of every pixel.
    ///
    /// # Shapes
    /// `coords`: `[B, 2, H, W]` → `[B, levels·(2r+1)², H, W]`
    pub fn lookup(&self, coords: Tensor<4>) -> Tensor<4> {
        let (b, h, w, r) = (self.batch, self.height, self.width, self.radius);
        let n = b * h * w;
        let c = coords.permute([0, 2, 3, 1]).reshape([n, 2]); // [N, 2] = (x, y)
        let k = 2 * r + 1;
        let mut out = Vec::with_capacity(self.levels.len());
        for (l, (level, &(hl, wl))) in self.levels.iter().zip(&self.sizes).enumerate() {
            let scaled = c.clone().div_scalar((1u32 << l) as f32);
            let window = window_lookup(level.clone(), scaled, hl, wl, r); // [N, k, k]
            out.push(window.reshape([b, h, w, k * k]));
        }
        Tensor::cat(out, 3).permute([0, 3, 1, 2]) // [B, L·k², H, W]
    }
}

/// Bilinear lookup of a (2r+1)² window with zero padding outside the level: one gather of the
/// (2r+2)² integer window per pixel, then four shifted slices blended with the shared fractional
/// weights. Same values as grid_sample (align_corners = true), but cheaper under autodiff.
///
/// # Shapes
/// `level`: `[N, hl, wl]`, `c`: `[N, 2]` → `[N, 2r+1 (dy), 2r+1 (dx)]`
fn window_lookup(level: Tensor<3>, c: Tensor<2>, hl: usize, wl: usize, r: usize) -> Tensor<3> {
    let device = level.device();
    let [n, _] = c.dims();
    let (k, kk) = (2 * r + 1, 2 * r + 2);
    let offs = Tensor::<1, Int>::arange(0..kk as i64, &device).reshape([1, kk]);
    let (x, y) = (c.clone().narrow(1, 0, 1), c.narrow(1, 1, 1));
    let (xf, yf) = (x.clone().floor(), y.clone().floor());
    let fx = (x - xf.clone()).reshape([n, 1, 1]);
    let fy = (y - yf.clone()).reshape([n, 1, 1]);
    let ix = xf.int().sub_scalar(r as i64) + offs.clone(); // [N, kk]
    let iy = yf.int().sub_scalar(r as i64) + offs;
    let vx = ix
        .clone()
        .greater_equal_elem(0)
        .bool_and(ix.clone().lower_elem(wl as i64))
        .float();
    let vy = iy
        .clone()
        .greater_equal_elem(0)
        .bool_and(iy.clone().lower_elem(hl as i64))
        .float();
    let idx = (iy
        .clamp(0, hl as i64 - 1)
        .reshape([n, kk, 1])
        .mul_scalar(wl as i64)
        + ix.clamp(0, wl as i64 - 1).reshape([n, 1, kk]))
    .reshape([n, kk * kk]);
    let p = level
        .reshape([n, hl * wl])
        .gather(1, idx)
        .reshape([n, kk, kk])
        * (vy.reshape([n, kk, 1]) * vx.reshape([n, 1, kk]));
    let s = |i: usize, j: usize| p.clone().slice([0..n, i..i + k, j..j + k]);
    let (gx, gy) = (fx.clone().neg() + 1.0, fy.clone().neg() + 1.0);
    s(0, 0) * (gy.clone() * gx.clone())
        + s(0, 1) * (gy * fx.clone())
        + s(1, 0) * (fy.clone() * gx)
        + s(1, 1) * (fy * fx)
}

#[cfg(test)]
mod tests {
    use super::*;

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
        assert!(
            (v[3] - 0.5).abs() < 1e-5 && (v[4] - 1.5).abs() < 1e-5 && (v[5] - 2.5).abs() < 1e-5,
            "{v:?}"
        );
        // Far outside: zero padding, finite.
        let far = Tensor::<4>::zeros([1, 2, 4, 4], &dev).add_scalar(1e4);
        let o: Vec<f32> = pyr.lookup(far).into_data().try_to_vec::<f32>().unwrap();
        assert!(o.iter().all(|x| *x == 0.0));
    }
}
