//! The correlation pyramid and its lookup (Note S9) as two operations: [`corr_pyramid`] builds
//! the all-pairs volume `C[p, q] = f1[:, p] · f2[:, q] / √C` and its 2×2-pooled levels, and
//! [`corr_lookup`] reads the (2r+1)² bilinear window around every pixel's position at every
//! level. The route is chosen once, when the pyramid is built, from the features:
//!
//! - plain CPU tensors: the volume and its levels on host memory
//!   ([`crate::flow::kernels::corr`]), every lookup a direct loop over the window
//!   ([`crate::flow::kernels::lookup`]) — without the dozen intermediate tensors per level that
//!   the tensor form allocates;
//! - training on the CPU: the volume and pooling as Burn operations (differentiable, so the
//!   gradients reach the features), each level's lookup one tracked operation
//!   ([`super::corr_backward`]);
//! - elsewhere: Burn's operations throughout, the lookup one gather of the (2r+2)² integer patch
//!   per pixel blended with the shared bilinear weights.

use burn::prelude::*;
use burn::tensor::module::avg_pool2d;
use burn::tensor::ops::AvgPoolOptions;

use super::bridge::HostView;
use super::route::{Operand, Route};
use crate::flow::kernels::{corr as kernel, lookup};

/// The correlation pyramid of one image pair: levels `[B·H·W, h_l, w_l]` for `l` in
/// `0..levels`, `h_0 = H`, `w_0 = W`.
pub struct Pyramid {
    levels: Levels,
    sizes: Vec<(usize, usize)>,
    batch: usize,
    height: usize,
    width: usize,
    route: Route,
}

enum Levels {
    /// Row-major host memory.
    Host(Vec<Vec<f32>>),
    /// Tensors, differentiable.
    Tensors(Vec<Tensor<3>>),
}

/// The pyramid of `num_levels` levels of the features of both frames.
///
/// # Shapes
/// `f1`, `f2`: `[B, C, H, W]` → levels `[B·H·W, H/2^l, W/2^l]`
pub fn corr_pyramid(f1: Tensor<4>, f2: Tensor<4>, num_levels: usize) -> Pyramid {
    let route = Route::of([Operand::of(&f1), Operand::of(&f2)]);
    build(f1, f2, num_levels, route)
}

/// Every level's window around `coords`, the (x, y) position in frame 2 of every pixel; level
/// l of image b fills channels `[l·(2r+1)², (l+1)·(2r+1)²)`. The positions carry no gradient.
///
/// # Shapes
/// `coords`: `[B, 2, H, W]` → `[B, levels·(2r+1)², H, W]`
pub fn corr_lookup(pyramid: &Pyramid, coords: Tensor<4>, radius: usize) -> Tensor<4> {
    let p = pyramid;
    let (b, h, w) = (p.batch, p.height, p.width);
    let device = coords.device();
    match &p.levels {
        Levels::Host(levels) => {
            if let Some(c) = HostView::of(coords.clone()) {
                let host: Vec<&[f32]> = levels.iter().map(|l| l.as_slice()).collect();
                let out = lookup::lookup_levels(&host, &p.sizes, c.values(), [b, h, w], radius);
                let k = 2 * radius + 1;
                return Tensor::from_data(
                    TensorData::new(out, [b, levels.len() * k * k, h, w]),
                    &device,
                );
            }
            // Positions that cannot be read on the host: the tensor form on the same values.
            let levels: Vec<Tensor<3>> = levels
                .iter()
                .zip(&p.sizes)
                .map(|(d, &(hl, wl))| {
                    Tensor::from_data(TensorData::new(d.clone(), [b * h * w, hl, wl]), &device)
                })
                .collect();
            lookup_tensor(p, &levels, coords, radius)
        }
        Levels::Tensors(levels) => {
            if p.route == Route::HostAutodiff {
                let windows: Option<Vec<Tensor<4>>> = levels
                    .iter()
                    .enumerate()
                    .map(|(l, level)| super::corr_backward::tracked(level, &coords, radius, l))
                    .collect();
                if let Some(windows) = windows {
                    return Tensor::cat(windows, 1); // [B, L·k², H, W]
                }
            }
            lookup_tensor(p, levels, coords, radius)
        }
    }
}

/// Builds the levels on `route`: on host memory for [`Route::Host`], as tensors otherwise.
fn build(f1: Tensor<4>, f2: Tensor<4>, num_levels: usize, route: Route) -> Pyramid {
    let [b, c, h, w] = f1.dims();
    if route == Route::Host
        && let (Some(a), Some(bv)) = (HostView::of(f1.clone()), HostView::of(f2.clone()))
    {
        let (levels, sizes) = kernel::pyramid(a.values(), bv.values(), [b, c, h, w], num_levels);
        return Pyramid {
            levels: Levels::Host(levels),
            sizes,
            batch: b,
            height: h,
            width: w,
            route,
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
        levels.push(level.reshape([n, hl, wl]));
    }
    Pyramid {
        levels: Levels::Tensors(levels),
        sizes,
        batch: b,
        height: h,
        width: w,
        route,
    }
}

/// The lookup as tensor operations, differentiable on any device.
fn lookup_tensor(p: &Pyramid, levels: &[Tensor<3>], coords: Tensor<4>, r: usize) -> Tensor<4> {
    let (b, h, w) = (p.batch, p.height, p.width);
    let n = b * h * w;
    let c = coords.permute([0, 2, 3, 1]).reshape([n, 2]); // [N, 2] = (x, y)
    let k = 2 * r + 1;
    let mut out = Vec::with_capacity(levels.len());
    for (l, (level, &(hl, wl))) in levels.iter().zip(&p.sizes).enumerate() {
        let scaled = c.clone().div_scalar((1u32 << l) as f32);
        let window = window_lookup(level.clone(), scaled, hl, wl, r); // [N, k, k]
        out.push(window.reshape([b, h, w, k * k]));
    }
    Tensor::cat(out, 3).permute([0, 3, 1, 2]) // [B, L·k², H, W]
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
    use crate::flow::kernels::testing::{Tol, cases};
    use crate::flow::ops::testing::{assert_tensors_close, random};
    use rand::RngExt;

    /// A random pair of feature maps and positions inside, across and far outside every level.
    struct Case {
        f1: Tensor<4>,
        f2: Tensor<4>,
        coords: Tensor<4>,
        levels: usize,
        radius: usize,
    }

    fn random_case(case: u64, dev: &Device) -> Case {
        let mut r = cases("corr vs tensor form", case);
        let shape = [
            r.random_range(1..=2),
            r.random_range(1..=6),
            r.random_range(1..=8),
            r.random_range(1..=9),
        ];
        let reach = shape[2].max(shape[3]) as f32 + 8.0;
        let (levels, radius) = (r.random_range(1..=4), r.random_range(1..=3));
        fixed_case(case, shape, (-reach, 2.0 * reach), levels, radius, dev)
    }

    /// Features of `shape`, positions uniform in `range`.
    fn fixed_case(
        seed: u64,
        shape: [usize; 4],
        range: (f32, f32),
        levels: usize,
        radius: usize,
        dev: &Device,
    ) -> Case {
        let mut r = cases("corr features", seed);
        let [b, _, h, w] = shape;
        let coords: Vec<f32> = (0..b * 2 * h * w)
            .map(|_| r.random_range(range.0..range.1))
            .collect();
        Case {
            f1: random(&mut r, shape, 1.0, dev),
            f2: random(&mut r, shape, 1.0, dev),
            coords: Tensor::from_data(TensorData::new(coords, [b, 2, h, w]), dev),
            levels,
            radius,
        }
    }

    /// Property: the host pyramid and lookup (inference) give the tensor form's windows, on
    /// random sizes, levels, radii and positions (seeded), including the network's own shape.
    #[test]
    fn host_lookup_matches_the_tensor_form() {
        let dev = Device::flex();
        // The former fixed case: 3 levels, radius 2, positions from −12 to +20 px.
        let fixed = fixed_case(1000, [2, 5, 6, 9], (-12.0, 20.0), 3, 2, &dev);
        for (case, c) in (0..30)
            .map(|i| (i, random_case(i, &dev)))
            .chain([(1000, fixed)])
        {
            let Case {
                f1,
                f2,
                coords,
                levels,
                radius,
            } = c;
            let host = corr_pyramid(f1.clone(), f2.clone(), levels);
            assert!(matches!(host.levels, Levels::Host(_)));
            let tensors = build(f1, f2, levels, Route::Burn);
            let got = corr_lookup(&host, coords.clone(), radius);
            let want = corr_lookup(&tensors, coords, radius);
            let what = format!("case {case}: {levels} levels, radius {radius}");
            assert_tensors_close(got, want, Tol::Abs(1e-5), &what);
        }
    }

    /// Property: under autodiff, the tracked lookup gives the tensor form's windows and the
    /// same gradients with respect to both feature maps, positions outside the levels included.
    #[test]
    fn training_lookup_matches_the_tensor_form_and_its_gradients() {
        let dev = Device::flex().autodiff();
        let fixed = fixed_case(1001, [2, 4, 6, 8], (-6.0, 14.0), 3, 2, &dev);
        for (case, c) in (0..16)
            .map(|i| (i, random_case(i, &dev)))
            .chain([(1001, fixed)])
        {
            let Case {
                f1: f10,
                f2: f20,
                coords,
                levels,
                radius,
            } = c;
            let k2 = (2 * radius + 1).pow(2);
            let [b, _, h, w] = f10.dims();
            let mut r = cases("corr loss weights", case);
            let weights = random(&mut r, [b, levels * k2, h, w], 1.0, &dev);
            let run = |route: Route| {
                let (f1, f2) = (
                    f10.clone().detach().require_grad(),
                    f20.clone().detach().require_grad(),
                );
                let pyramid = build(f1.clone(), f2.clone(), levels, route);
                let out = corr_lookup(&pyramid, coords.clone(), radius);
                let g = (out.clone() * weights.clone()).sum().backward();
                (
                    out.inner(),
                    f1.grad(&g).expect("f1 gradient"),
                    f2.grad(&g).expect("f2 gradient"),
                )
            };
            let (oa, a1, a2) = run(Route::HostAutodiff);
            let (ob, b1, b2) = run(Route::BurnAutodiff);
            let what = |q: &str| format!("case {case} {q}: {levels} levels, radius {radius}");
            assert_tensors_close(oa, ob, Tol::Abs(1e-5), &what("windows"));
            assert_tensors_close(a1, b1, Tol::Abs(1e-4), &what("f1 gradient"));
            assert_tensors_close(a2, b2, Tol::Abs(1e-4), &what("f2 gradient"));
        }
        let plain = corr_pyramid(
            Tensor::<4>::zeros([1, 2, 3, 3], &dev),
            Tensor::<4>::zeros([1, 2, 3, 3], &dev),
            2,
        );
        assert_eq!(plain.route, Route::HostAutodiff);
    }
}
