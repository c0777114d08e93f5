//! All-pairs correlation (Note S9): the dot products of every 1/8-resolution feature of frame 1
//! with every one of frame 2, scaled by 1/√C, pooled into a pyramid, and looked up in a
//! (2r+1)² window around x + F(x) at every level by bilinear interpolation.
//!
//! Under autodiff the lookup is built from tensor operations so that gradients reach the
//! features. Without autodiff (inference) on the CPU the pyramid moves to host memory and every
//! lookup is a direct loop over the window: the same numbers, without the dozen intermediate
//! tensors per level that the tensor form allocates.

use burn::prelude::*;
use burn::tensor::module::avg_pool2d;
use burn::tensor::ops::AvgPoolOptions;
use rayon::prelude::*;

use super::corr_lookup_op::{lookup_level_train, lookup_levels_host};

/// One pyramid level `[B·H·W, H/2^l, W/2^l]`.
enum Level {
    /// A tensor, differentiable.
    Graph(Tensor<3>),
    /// Row-major host memory.
    Host(Vec<f32>),
}

/// The correlation pyramid of one image pair.
pub struct CorrPyramid {
    levels: Vec<Level>,
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
        // The host loop only pays on the CPU backend; a GPU keeps its pyramid on the device.
        let host = !f1.is_autodiff() && !f2.is_autodiff() && f1.device() == Device::flex();
        Self::build(f1, f2, num_levels, radius, host)
    }

    /// The pyramid as tensors, differentiable, whatever the device.
    pub fn graph(f1: Tensor<4>, f2: Tensor<4>, num_levels: usize, radius: usize) -> Self {
        Self::build(f1, f2, num_levels, radius, false)
    }

    /// Builds the levels; with `host`, on host memory (see [`host_pyramid`]).
    fn build(f1: Tensor<4>, f2: Tensor<4>, num_levels: usize, radius: usize, host: bool) -> Self {
        let [b, c, h, w] = f1.dims();
        if host
            && let (Ok(a), Ok(bv)) = (
                f1.clone().into_data().try_into_vec::<f32>(),
                f2.clone().into_data().try_into_vec::<f32>(),
            )
        {
            let (levels, sizes) = host_pyramid(&a, &bv, [b, c, h, w], num_levels);
            return Self {
                levels: levels.into_iter().map(Level::Host).collect(),
                sizes,
                batch: b,
                height: h,
                width: w,
                radius,
            };
        }
        let corr = f1
            .reshape([b, c, h * w])
            .swap_dims(1, 2)
            .matmul(f2.reshape([b, c, h * w])) // [B, HW, HW]
            .div_scalar((c as f32).sqrt())
            .reshape([b * h * w, 1, h, w]);
        let mut levels = Vec::with_capacity(num_levels);
        let mut sizes = Vec::with_capacity(num_levels);
        let mut cur = Some(corr);
        for l in 0..num_levels {
            let Some(level) = cur.take() else { break };
            let [n, _, hl, wl] = level.dims();
            sizes.push((hl, wl));
            if l + 1 < num_levels {
                // A level already 1 cell wide cannot be halved; keep it (the coordinates still
                // scale, so the lookup then sees mostly zero padding, as RAFT's does).
                let k = [2.min(hl), 2.min(wl)];
                cur = Some(avg_pool2d(
                    level.clone(),
                    AvgPoolOptions::new(k).with_stride(k),
                ));
            }
            levels.push(Level::Graph(level.reshape([n, hl, wl])));
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
        let device = coords.device();
        let host: Option<Vec<&[f32]>> = self
            .levels
            .iter()
            .map(|l| match l {
                Level::Host(d) => Some(d.as_slice()),
                Level::Graph(_) => None,
            })
            .collect();
        if let Some(host) = host
            && let Ok(c) = coords.clone().into_data().try_into_vec::<f32>()
        {
            let k = 2 * r + 1;
            let out = lookup_levels_host(&host, &self.sizes, &c, [b, h, w], r);
            return Tensor::from_data(TensorData::new(out, [b, host.len() * k * k, h, w]), &device);
        }
        let levels: Vec<Tensor<3>> = self
            .levels
            .iter()
            .enumerate()
            .map(|(i, l)| match l {
                Level::Graph(t) => t.clone(),
                // Host levels with coordinates that cannot be read as f32.
                Level::Host(d) => {
                    let (hl, wl) = self.sizes[i];
                    Tensor::from_data(TensorData::new(d.clone(), [b * h * w, hl, wl]), &device)
                }
            })
            .collect();
        self.lookup_graph(&levels, coords)
    }

    /// Under autodiff on the CPU backend, one host operation per level
    /// ([`super::corr_lookup_op`]); otherwise [`Self::lookup_tensor`].
    fn lookup_graph(&self, levels: &[Tensor<3>], coords: Tensor<4>) -> Tensor<4> {
        if levels.iter().any(|l| l.is_autodiff()) {
            let host: Option<Vec<Tensor<4>>> = levels
                .iter()
                .enumerate()
                .map(|(l, level)| lookup_level_train(level, &coords, self.radius, l))
                .collect();
            if let Some(windows) = host {
                return Tensor::cat(windows, 1); // [B, L·k², H, W]
            }
        }
        self.lookup_tensor(levels, coords)
    }

    /// The lookup as tensor operations, differentiable on any device.
    fn lookup_tensor(&self, levels: &[Tensor<3>], coords: Tensor<4>) -> Tensor<4> {
        let (b, h, w, r) = (self.batch, self.height, self.width, self.radius);
        let n = b * h * w;
        let c = coords.permute([0, 2, 3, 1]).reshape([n, 2]); // [N, 2] = (x, y)
        let k = 2 * r + 1;
        let mut out = Vec::with_capacity(levels.len());
        for (l, (level, &(hl, wl))) in levels.iter().zip(&self.sizes).enumerate() {
            let scaled = c.clone().div_scalar((1u32 << l) as f32);
            let window = window_lookup(level.clone(), scaled, hl, wl, r); // [N, k, k]
            out.push(window.reshape([b, h, w, k * k]));
        }
        Tensor::cat(out, 3).permute([0, 3, 1, 2]) // [B, L·k², H, W]
    }
}

/// The correlation pyramid on host memory: level 0 is one matrix product per image,
/// `corr[p, q] = f1[:, p] · f2[:, q] / √C`, written straight into the level; every further level
/// is the 2×2 average of the one before (1 cell wide sides are kept), as `avg_pool2d` gives.
///
/// # Shapes
/// `f1`, `f2`: `[B, C, H, W]` → levels `[B·H·W, h_l, w_l]` with their `(h_l, w_l)`
fn host_pyramid(
    f1: &[f32],
    f2: &[f32],
    [b, c, h, w]: [usize; 4],
    num_levels: usize,
) -> (Vec<Vec<f32>>, Vec<(usize, usize)>) {
    let hw = h * w;
    let mut level = vec![0f32; b * hw * hw];
    for bi in 0..b {
        let (a, bb) = (
            &f1[bi * c * hw..(bi + 1) * c * hw],
            &f2[bi * c * hw..(bi + 1) * c * hw],
        );
        let dst = &mut level[bi * hw * hw..(bi + 1) * hw * hw];
        if hw == 0 {
            continue;
        }
        // SAFETY: dst is [HW, HW] row-major; lhs reads f1 as its transpose [HW, C] (row stride
        // 1, column stride HW) and rhs f2 as [C, HW]; all three stay inside their slices.
        unsafe {
            gemm::gemm(
                hw,
                hw,
                c,
                dst.as_mut_ptr(),
                1,
                hw as isize,
                false,
                a.as_ptr(),
                hw as isize,
                1,
                bb.as_ptr(),
                1,
                hw as isize,
                0.0f32,
                1.0 / (c as f32).sqrt(),
                false,
                false,
                false,
                gemm::Parallelism::Rayon(0),
            );
        }
    }
    let n = b * hw;
    let mut levels = Vec::with_capacity(num_levels);
    let mut sizes = Vec::with_capacity(num_levels);
    let (mut hl, mut wl) = (h, w);
    for l in 0..num_levels {
        sizes.push((hl, wl));
        if l + 1 < num_levels {
            let (kh, kw) = (2.min(hl), 2.min(wl));
            let (h2, w2) = (hl / kh, wl / kw);
            let mut next = vec![0f32; n * h2 * w2];
            let inv = 1.0 / (kh * kw) as f32;
            if h2 * w2 > 0 {
                next.par_chunks_mut(h2 * w2)
                    .zip(level.par_chunks(hl * wl))
                    .for_each(|(dst, src)| {
                        for y in 0..h2 {
                            for x in 0..w2 {
                                let mut sum = 0.0;
                                for dy in 0..kh {
                                    let row = &src[(y * kh + dy) * wl + x * kw..];
                                    sum += row[..kw].iter().sum::<f32>();
                                }
                                dst[y * w2 + x] = sum * inv;
                            }
                        }
                    });
            }
            levels.push(std::mem::replace(&mut level, next));
            (hl, wl) = (h2, w2);
        } else {
            levels.push(std::mem::take(&mut level));
        }
    }
    (levels, sizes)
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
    use burn::tensor::Distribution;

    /// The host lookup (inference) gives the numbers of the tensor lookup (training), for
    /// positions inside, across and far outside every level.
    #[test]
    fn host_lookup_matches_the_tensor_lookup() {
        let dev = Device::flex();
        let (b, c, h, w) = (2, 5, 6, 9);
        let f1 = Tensor::<4>::random([b, c, h, w], Distribution::Normal(0.0, 1.0), &dev);
        let f2 = Tensor::<4>::random([b, c, h, w], Distribution::Normal(0.0, 1.0), &dev);
        let host = CorrPyramid::new(f1.clone(), f2.clone(), 3, 2);
        assert!(host.levels.iter().all(|l| matches!(l, Level::Host(_))));
        let graph = CorrPyramid::graph(f1, f2, 3, 2);
        // Positions from −12 to +20 px: inside, at the border and outside all levels.
        let coords = Tensor::<4>::random([b, 2, h, w], Distribution::Uniform(-12.0, 20.0), &dev);
        let a = host.lookup(coords.clone());
        let g = graph.lookup(coords);
        assert_eq!(a.dims(), [b, 3 * 25, h, w]);
        let diff: f32 = (a - g).abs().max().into_scalar();
        assert!(diff < 1e-5, "max difference {diff}");
    }

    /// Under autodiff, the host operation gives the tensor lookup's windows and the same
    /// gradients with respect to both feature maps, positions outside the levels included.
    #[test]
    fn training_lookup_matches_the_tensor_lookup_and_its_gradients() {
        let dev = Device::flex().autodiff();
        let (b, c, h, w) = (2, 4, 6, 8);
        let f10 = Tensor::<4>::random([b, c, h, w], Distribution::Normal(0.0, 1.0), &dev);
        let f20 = Tensor::<4>::random([b, c, h, w], Distribution::Normal(0.0, 1.0), &dev);
        let coords = Tensor::<4>::random([b, 2, h, w], Distribution::Uniform(-6.0, 14.0), &dev);
        let weights = Tensor::<4>::random([b, 3 * 25, h, w], Distribution::Normal(0.0, 1.0), &dev);
        let run = |host: bool| {
            let (f1, f2) = (
                f10.clone().detach().require_grad(),
                f20.clone().detach().require_grad(),
            );
            let pyr = CorrPyramid::graph(f1.clone(), f2.clone(), 3, 2);
            let levels: Vec<Tensor<3>> = pyr
                .levels
                .iter()
                .map(|l| match l {
                    Level::Graph(t) => t.clone(),
                    Level::Host(_) => unreachable!("graph levels"),
                })
                .collect();
            let out = if host {
                pyr.lookup_graph(&levels, coords.clone())
            } else {
                pyr.lookup_tensor(&levels, coords.clone())
            };
            let g = (out.clone() * weights.clone()).sum().backward();
            (
                out.inner(),
                f1.grad(&g).expect("f1 gradient"),
                f2.grad(&g).expect("f2 gradient"),
            )
        };
        let (oa, a1, a2) = run(true);
        let (ob, b1, b2) = run(false);
        let d = |x: Tensor<4>, y: Tensor<4>| -> f32 { (x - y).abs().max().into_scalar() };
        assert!(d(oa, ob) < 1e-5, "windows");
        assert!(d(a1, b1) < 1e-4, "f1 gradient");
        assert!(d(a2, b2) < 1e-4, "f2 gradient");
    }

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
