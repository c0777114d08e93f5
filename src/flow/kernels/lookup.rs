//! The correlation lookup of Note S9 on host values: around every pixel's position x + F(x),
//! scaled to level l by 2^−l, the (2r+1)² window of the level read by bilinear interpolation,
//! zero outside the level. The forward pass gathers the (2r+2)² integer patch once and applies
//! the bilinear weights separably; the backward pass adds the window's gradient back onto the
//! four corners of every tap, each pixel into its own correlation map (so pixels run in
//! parallel without conflicts). The positions carry no gradient, as in RAFT.

use rayon::prelude::*;

/// Sizes of one lookup.
#[derive(Clone, Copy, Debug)]
pub struct Window {
    /// Images, rows and columns of the 1/8-resolution grid.
    pub b: usize,
    pub h: usize,
    pub w: usize,
    /// Level size.
    pub hl: usize,
    pub wl: usize,
    pub r: usize,
    /// 2^−level: pixel positions to level positions.
    pub scale: f32,
}

impl Window {
    pub fn k(&self) -> usize {
        2 * self.r + 1
    }

    /// The top-left integer tap and the fractional offsets of pixel n.
    fn anchor(&self, coords: &[f32], n: usize) -> (i64, i64, f32, f32) {
        let hw = self.h * self.w;
        let (bi, p) = (n / hw, n % hw);
        let x = coords[(2 * bi) * hw + p] * self.scale;
        let y = coords[(2 * bi + 1) * hw + p] * self.scale;
        let (xf, yf) = (x.floor(), y.floor());
        // Saturating casts, kept far from overflow when offsets are added.
        let bound = 1i64 << 40;
        (
            (xf as i64).clamp(-bound, bound) - self.r as i64,
            (yf as i64).clamp(-bound, bound) - self.r as i64,
            x - xf,
            y - yf,
        )
    }

    /// The rows and columns of the level under the `(k+1)²` patch at `(y0, x0)`: the patch
    /// index range `[lo, hi)` that lies inside `[0, size)`, for an anchor `a0`.
    fn inside(a0: i64, k1: usize, size: usize) -> (usize, usize) {
        let lo = (-a0).clamp(0, k1 as i64) as usize;
        let hi = (size as i64 - a0).clamp(lo as i64, k1 as i64) as usize;
        (lo, hi)
    }

    /// The `(k+1)²` values of `map` under the patch at `(y0, x0)`, zero outside the level.
    fn gather(&self, map: &[f32], x0: i64, y0: i64, patch: &mut [f32]) {
        let k1 = self.k() + 1;
        let (r_lo, r_hi) = Self::inside(y0, k1, self.hl);
        let (c_lo, c_hi) = Self::inside(x0, k1, self.wl);
        patch.fill(0.0);
        if c_lo == c_hi {
            return;
        }
        for a in r_lo..r_hi {
            let row = (y0 + a as i64) as usize * self.wl;
            let first = row + (x0 + c_lo as i64) as usize;
            patch[a * k1 + c_lo..a * k1 + c_hi].copy_from_slice(&map[first..first + c_hi - c_lo]);
        }
    }

    /// Adds the `(k+1)²` patch at `(y0, x0)` onto `map`, dropping what falls outside the level.
    fn scatter(&self, patch: &[f32], x0: i64, y0: i64, map: &mut [f32]) {
        let k1 = self.k() + 1;
        let (r_lo, r_hi) = Self::inside(y0, k1, self.hl);
        let (c_lo, c_hi) = Self::inside(x0, k1, self.wl);
        if c_lo == c_hi {
            return;
        }
        for a in r_lo..r_hi {
            let row = (y0 + a as i64) as usize * self.wl;
            let first = row + (x0 + c_lo as i64) as usize;
            for (m, v) in map[first..first + c_hi - c_lo]
                .iter_mut()
                .zip(&patch[a * k1 + c_lo..a * k1 + c_hi])
            {
                *m += v;
            }
        }
    }

    /// # Shapes
    /// `level` `[B·H·W, hl, wl]`, `coords` `[B, 2, H, W]` → `[B, (2r+1)², H, W]`
    pub fn forward(&self, level: &[f32], coords: &[f32]) -> Vec<f32> {
        let (k, hw, m) = (self.k(), self.h * self.w, self.hl * self.wl);
        let k1 = k + 1;
        let mut windows = vec![0f32; self.b * hw * k * k];
        windows.par_chunks_mut(k * k).enumerate().for_each_init(
            || (vec![0f32; k1 * k1], vec![0f32; k1 * k]),
            |(patch, across), (n, dst)| {
                let (x0, y0, fx, fy) = self.anchor(coords, n);
                self.gather(&level[n * m..(n + 1) * m], x0, y0, patch);
                // Bilinear weights, separably: across each row of the patch, then down.
                let (gx, gy) = (1.0 - fx, 1.0 - fy);
                for (row, out) in patch.chunks_exact(k1).zip(across.chunks_exact_mut(k)) {
                    for (j, o) in out.iter_mut().enumerate() {
                        *o = gx * row[j] + fx * row[j + 1];
                    }
                }
                for (i, out) in dst.chunks_exact_mut(k).enumerate() {
                    let (top, bottom) = (
                        &across[i * k..(i + 1) * k],
                        &across[(i + 1) * k..(i + 2) * k],
                    );
                    for ((o, t), b) in out.iter_mut().zip(top).zip(bottom) {
                        *o = gy * t + fy * b;
                    }
                }
            },
        );
        // Pixel-major → channel-major per image.
        let mut out = vec![0f32; windows.len()];
        for bi in 0..self.b {
            let src = &windows[bi * hw * k * k..(bi + 1) * hw * k * k];
            let dst = &mut out[bi * k * k * hw..(bi + 1) * k * k * hw];
            for (p, row) in src.chunks_exact(k * k).enumerate() {
                for (c, v) in row.iter().enumerate() {
                    dst[c * hw + p] = *v;
                }
            }
        }
        out
    }

    /// Gradient of the level given the gradient `g` `[B, (2r+1)², H, W]` of the window: the
    /// forward pass's two interpolations transposed, then added onto the level.
    ///
    /// # Shapes
    /// → `[B·H·W, hl, wl]`
    pub fn backward(&self, coords: &[f32], g: &[f32]) -> Vec<f32> {
        let (k, hw, m) = (self.k(), self.h * self.w, self.hl * self.wl);
        let k1 = k + 1;
        let mut dlevel = vec![0f32; self.b * hw * m];
        dlevel.par_chunks_mut(m.max(1)).enumerate().for_each_init(
            || (vec![0f32; k1 * k1], vec![0f32; k1 * k]),
            |(patch, across), (n, map)| {
                let (bi, p) = (n / hw, n % hw);
                let (x0, y0, fx, fy) = self.anchor(coords, n);
                let (gx, gy) = (1.0 - fx, 1.0 - fy);
                across.fill(0.0);
                for i in 0..k {
                    for j in 0..k {
                        let gv = g[(bi * k * k + i * k + j) * hw + p];
                        across[i * k + j] += gy * gv;
                        across[(i + 1) * k + j] += fy * gv;
                    }
                }
                patch.fill(0.0);
                for (row, d) in patch.chunks_exact_mut(k1).zip(across.chunks_exact(k)) {
                    for (j, &v) in d.iter().enumerate() {
                        row[j] += gx * v;
                        row[j + 1] += fx * v;
                    }
                }
                self.scatter(patch, x0, y0, map);
            },
        );
        dlevel
    }
}

/// Every level's windows on host memory, for inference: level l of image b fills channels
/// `[l·(2r+1)², (l+1)·(2r+1)²)`.
///
/// # Shapes
/// `levels[l]` `[B·H·W, h_l, w_l]`, `coords` `[B, 2, H, W]` → `[B, L·(2r+1)², H, W]`
pub fn lookup_levels(
    levels: &[&[f32]],
    sizes: &[(usize, usize)],
    coords: &[f32],
    [b, h, w]: [usize; 3],
    r: usize,
) -> Vec<f32> {
    let (k2, hw) = ((2 * r + 1).pow(2), h * w);
    let lk = levels.len() * k2;
    let mut out = vec![0f32; b * lk * hw];
    for (l, (level, &(hl, wl))) in levels.iter().zip(sizes).enumerate() {
        let scale = 1.0 / (1u64 << l) as f32;
        let part = Window {
            b,
            h,
            w,
            hl,
            wl,
            r,
            scale,
        }
        .forward(level, coords); // [B, k², H, W]
        for bi in 0..b {
            out[(bi * lk + l * k2) * hw..(bi * lk + (l + 1) * k2) * hw]
                .copy_from_slice(&part[bi * k2 * hw..(bi + 1) * k2 * hw]);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flow::kernels::testing::{Tol, assert_close, cases, values};
    use rand::RngExt;

    /// The window value at tap (i, j) by the definition: bilinear interpolation of the level at
    /// (x·s − r + j, y·s − r + i), zero outside.
    fn bilinear(level: &[f32], hl: usize, wl: usize, x: f32, y: f32) -> f32 {
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let at = |yy: f32, xx: f32| {
            if yy < 0.0 || xx < 0.0 || yy >= hl as f32 || xx >= wl as f32 {
                0.0
            } else {
                level[yy as usize * wl + xx as usize]
            }
        };
        (1.0 - fy) * ((1.0 - fx) * at(y0, x0) + fx * at(y0, x0 + 1.0))
            + fy * ((1.0 - fx) * at(y0 + 1.0, x0) + fx * at(y0 + 1.0, x0 + 1.0))
    }

    /// Property: on random sizes, radii, levels and positions inside, across and far outside
    /// the level (seeded), the forward pass is bilinear interpolation and the backward pass its
    /// adjoint, ⟨lookup(level), g⟩ = ⟨level, ∂L/∂level⟩.
    #[test]
    fn windows_are_bilinear_reads_and_the_backward_pass_their_adjoint() {
        for case in 0..30 {
            let mut r = cases("corr lookup", case);
            let (b, h, w) = (
                r.random_range(1..=2),
                r.random_range(1..=4),
                r.random_range(1..=4),
            );
            let (hl, wl, radius) = (
                r.random_range(1..=6),
                r.random_range(1..=6),
                r.random_range(1..=3),
            );
            let scale = 1.0 / (1u32 << r.random_range(0..3)) as f32;
            let win = Window {
                b,
                h,
                w,
                hl,
                wl,
                r: radius,
                scale,
            };
            let n = b * h * w;
            let level = values(&mut r, n * hl * wl, 1.0);
            let coords: Vec<f32> = (0..b * 2 * h * w)
                .map(|_| r.random_range(-12.0f32..20.0))
                .collect();
            let k = win.k();
            let got = win.forward(&level, &coords);
            let hw = h * w;
            let mut want = vec![0f32; b * k * k * hw];
            for bi in 0..b {
                for p in 0..hw {
                    let (x, y) = (
                        coords[2 * bi * hw + p] * scale,
                        coords[(2 * bi + 1) * hw + p] * scale,
                    );
                    let map = &level[(bi * hw + p) * hl * wl..][..hl * wl];
                    for i in 0..k {
                        for j in 0..k {
                            let (tx, ty) =
                                (x - radius as f32 + j as f32, y - radius as f32 + i as f32);
                            want[(bi * k * k + i * k + j) * hw + p] = bilinear(map, hl, wl, tx, ty);
                        }
                    }
                }
            }
            let what = format!("case {case}: {win:?}");
            assert_close(&got, &want, Tol::Abs(1e-5), &what);
            let g = values(&mut r, got.len(), 1.0);
            let dlevel = win.backward(&coords, &g);
            let dot =
                |a: &[f32], b: &[f32]| a.iter().zip(b).map(|(u, v)| (u * v) as f64).sum::<f64>();
            let (lhs, rhs) = (dot(&got, &g), dot(&level, &dlevel));
            let scale = (lhs.abs() + 1.0) as f32;
            assert_close(
                &[rhs as f32 / scale],
                &[lhs as f32 / scale],
                Tol::Abs(1e-5),
                &format!("adjoint, {what}"),
            );
        }
    }
}
