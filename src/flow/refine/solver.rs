//! The variational refinement at one scale: minimise
//! E(du, dv) = Σ δ·Ψ(n1·(Iz + Ix·du + Iy·dv)²) + γ·Ψ(nx·(Ixz + …)² + ny·(Iyz + …)²)
//!           + α·e^(−κ|∇I|/255)·Ψ(|∇(u + du)|² + |∇(v + dv)|²),  Ψ(s²) = √(s² + ε²)
//! (the local weight e^(−κ|∇I|/255) is DeepFlow's, `Terms::smooth`), by lagged fixed-point iterations on the robust weights, each solving the linear
//! Euler–Lagrange equations by red–black successive over-relaxation (Brox et al. 2004).
//!
//! Laid out for speed: each fixed-point iteration computes every pixel's coefficients once (its
//! 2×2 data system with the fixed part of the smoothness term folded in, and the edge weights),
//! so a sweep only reads them; the increments of each colour live in their own zero-bordered
//! array, so one colour's pass reads the other colour's array and writes its own, rows in
//! parallel, with no copy, no allocation and no border case inside the loop. The two row loops
//! are compiled for the CPU's widest vector instructions, chosen at run time (`multiversion`; no
//! fused multiply-adds are introduced, so every target gives the same bits).

use multiversion::multiversion;
use rayon::prelude::*;

use super::linearise::Terms;

/// ε of the robust penalty Ψ.
pub(super) const EPS: f32 = 1e-3;

/// Rows per parallel task (a row of a 512-wide frame is a few µs of work).
const ROWS: usize = 8;

/// The solver's settings at one scale.
#[derive(Clone, Copy, Debug)]
pub struct Weights {
    pub alpha: f32,
    pub delta: f32,
    pub gamma: f32,
    pub fixed_point_iters: usize,
    pub sor_iters: usize,
    pub omega: f32,
}

/// The fields of a pixel's equations within a fixed-point iteration, each a plane of the
/// split layout ([`Coefs`]). With the data system A·(du, dv) = b and the edge weights k_j to the
/// neighbours j, the Euler–Lagrange equation for du is
/// A11·du + A12·dv − b1 = Σ k_j·(u_j + du_j − u − du), i.e.
/// (A11 + Σ k_j)·du = b1 + Σ k_j·(u_j − u) − A12·dv + Σ k_j·du_j:
/// `D1` is the bracket on the left, `C1` the part on the right that stays fixed while the
/// sweeps run; likewise `D2`, `C2` for dv. `KL`, `KR`, `KU`, `KD` are the edge weights to the
/// left, right, upper and lower neighbour (zero outside the frame).
const C1: usize = 0;
const C2: usize = 1;
const A12: usize = 2;
const D1: usize = 3;
const D2: usize = 4;
const KL: usize = 5;
const KR: usize = 6;
const KU: usize = 7;
const KD: usize = 8;
const FIELDS: usize = 9;

/// Refines `(u, v)` (`[h·w]` each) in place with the linearised `terms`.
pub fn solve(t: &Terms, u: &mut [f32], v: &mut [f32], h: usize, w: usize, k: &Weights) {
    let n = h * w;
    let mut inc = Increments::new(h, w);
    let (mut du, mut dv) = (vec![0.0f32; n], vec![0.0f32; n]);
    let mut edges = Edges::new(h, w);
    let mut coefs = Coefs::new(h, w);
    for _ in 0..k.fixed_point_iters {
        inc.gather(&mut du, &mut dv);
        edges.update(u, v, &du, &dv, &t.smooth, k.alpha);
        coefs.update(t, u, v, &du, &dv, &edges, k);
        for _ in 0..k.sor_iters {
            for colour in 0..2 {
                inc.sweep(colour, &coefs, k.omega);
            }
        }
    }
    inc.gather(&mut du, &mut dv);
    u.iter_mut().zip(&du).for_each(|(u, d)| *u += d);
    v.iter_mut().zip(&dv).for_each(|(v, d)| *v += d);
}

/// The red–black split: the pixels of colour c = (x + y) mod 2 in row y are x = 2k + o with
/// o = (c + y) mod 2, stored at k = x / 2, `half(w)` places a row; the row holds `count(w, o)`.
fn half(w: usize) -> usize {
    w.div_ceil(2)
}

/// How many pixels of a row of `w` start at offset `o` and step by 2.
fn count(w: usize, o: usize) -> usize {
    w.saturating_sub(o).div_ceil(2)
}

/// The smoothness term's edge weights: α·Ψ′ at each pixel (forward differences of u + du and
/// v + dv), averaged onto the edges between neighbours; edges leaving the frame weigh zero.
struct Edges {
    h: usize,
    w: usize,
    /// α·Ψ′ per pixel, `[h·w]`.
    psi: Vec<f32>,
    /// `[h × (w+1)]`: entry (y, x) weighs the edge between pixels (x − 1, y) and (x, y);
    /// zero at x = 0 and x = w.
    horizontal: Vec<f32>,
    /// `[(h+1) × w]`: entry (y, x) weighs the edge between pixels (x, y − 1) and (x, y); zero
    /// at y = 0 and y = h.
    vertical: Vec<f32>,
}

impl Edges {
    fn new(h: usize, w: usize) -> Self {
        Self {
            h,
            w,
            psi: vec![0.0; h * w],
            horizontal: vec![0.0; h * (w + 1)],
            vertical: vec![0.0; (h + 1) * w],
        }
    }

    /// The weights at the flow `(u + du, v + dv)`, `local` the terms' per-pixel weight.
    fn update(&mut self, u: &[f32], v: &[f32], du: &[f32], dv: &[f32], local: &[f32], alpha: f32) {
        let (h, w) = (self.h, self.w);
        self.psi
            .par_chunks_mut(w)
            .enumerate()
            .with_min_len(ROWS)
            .for_each(|(y, row)| {
                for (x, p) in row.iter_mut().enumerate() {
                    let i = y * w + x;
                    let (uu, vv) = (u[i] + du[i], v[i] + dv[i]);
                    // Forward differences; zero past the last column or row.
                    let j = if x + 1 < w { i + 1 } else { i };
                    let mut g = (u[j] + du[j] - uu).powi(2) + (v[j] + dv[j] - vv).powi(2);
                    let j = if y + 1 < h { i + w } else { i };
                    g += (u[j] + du[j] - uu).powi(2) + (v[j] + dv[j] - vv).powi(2);
                    *p = alpha * local[i] / (g + EPS * EPS).sqrt();
                }
            });
        let psi = &self.psi;
        self.horizontal
            .par_chunks_mut(w + 1)
            .enumerate()
            .with_min_len(ROWS)
            .for_each(|(y, row)| {
                let p = &psi[y * w..(y + 1) * w];
                row[0] = 0.0;
                row[w] = 0.0;
                for x in 1..w {
                    row[x] = 0.5 * (p[x - 1] + p[x]);
                }
            });
        self.vertical
            .par_chunks_mut(w)
            .enumerate()
            .with_min_len(ROWS)
            .for_each(|(y, row)| {
                if y == 0 || y == h {
                    row.fill(0.0);
                } else {
                    let (up, at) = (&psi[(y - 1) * w..y * w], &psi[y * w..(y + 1) * w]);
                    for x in 0..w {
                        row[x] = 0.5 * (up[x] + at[x]);
                    }
                }
            });
    }
}

/// Every pixel's equations (the fields `C1` … `KD`) in the split layout: per colour, per row a
/// block of `FIELDS` planes of `half(w)` values.
struct Coefs {
    w: usize,
    colour: [Vec<f32>; 2],
}

impl Coefs {
    fn new(h: usize, w: usize) -> Self {
        let n = h * FIELDS * half(w);
        Self {
            w,
            colour: [vec![0.0; n], vec![0.0; n]],
        }
    }

    /// The equations at the increment `(du, dv)`: the data terms' robust weights and the
    /// resulting 2×2 system, with the smoothness term's fixed part and diagonal added.
    #[allow(clippy::too_many_arguments)]
    fn update(
        &mut self,
        t: &Terms,
        u: &[f32],
        v: &[f32],
        du: &[f32],
        dv: &[f32],
        e: &Edges,
        k: &Weights,
    ) {
        let (w, m) = (self.w, half(self.w));
        let [c0, c1] = &mut self.colour;
        c0.par_chunks_mut(FIELDS * m)
            .zip(c1.par_chunks_mut(FIELDS * m))
            .enumerate()
            .with_min_len(ROWS)
            .for_each_init(
                || vec![0.0f32; FIELDS * w + 2 * (w + 2)],
                |buf, (y, (colour0, colour1))| {
                    let (fields, pads) = buf.split_at_mut(FIELDS * w);
                    let (pu, pv) = pads.split_at_mut(w + 2);
                    equations_row(t, u, v, du, dv, e, k, y, fields, pu, pv);
                    // Into the split layout: colour c's pixels in row y are x = 2k + (c + y) % 2.
                    for (c, block) in [(0, colour0), (1, colour1)] {
                        let o = (c + y) % 2;
                        for f in 0..FIELDS {
                            let from = fields[f * w + o..(f + 1) * w].iter().step_by(2);
                            for (to, from) in block[f * m..(f + 1) * m].iter_mut().zip(from) {
                                *to = *from;
                            }
                        }
                    }
                },
            );
    }
}

/// Row `y` of `a`, rows of `w` values.
fn row(a: &[f32], y: usize, w: usize) -> &[f32] {
    &a[y * w..(y + 1) * w]
}

/// The `N` consecutive planes of `w` values in `out`.
fn planes<const N: usize>(out: &mut [f32], w: usize) -> [&mut [f32]; N] {
    let mut rest = out;
    std::array::from_fn(|_| {
        let (plane, tail) = std::mem::take(&mut rest).split_at_mut(w);
        rest = tail;
        plane
    })
}

/// Row `y`'s equations in the plain layout: `out` gets the `FIELDS` planes of `w` values; `pu`,
/// `pv` (`w + 2` each) are scratch. Every slice is cut to the row's length first, so the loop
/// runs without bounds checks and vectorises (square roots and divisions included).
#[allow(clippy::too_many_arguments)]
#[multiversion(targets = "simd")]
fn equations_row(
    t: &Terms,
    u: &[f32],
    v: &[f32],
    du: &[f32],
    dv: &[f32],
    e: &Edges,
    k: &Weights,
    y: usize,
    out: &mut [f32],
    pu: &mut [f32],
    pv: &mut [f32],
) {
    let (h, w) = (e.h, e.w);
    let (ix, iy, iz) = (row(&t.ix, y, w), row(&t.iy, y, w), row(&t.iz, y, w));
    let (ixx, ixy, iyy) = (row(&t.ixx, y, w), row(&t.ixy, y, w), row(&t.iyy, y, w));
    let (ixz, iyz) = (row(&t.ixz, y, w), row(&t.iyz, y, w));
    let (n1, nx, ny) = (row(&t.n1, y, w), row(&t.nx, y, w), row(&t.ny, y, w));
    let (ur, vr, dur, dvr) = (row(u, y, w), row(v, y, w), row(du, y, w), row(dv, y, w));
    // The rows above and below, clamped: outside the frame the edge weight is zero and the
    // neighbour stands at the pixel itself, so its difference is zero too.
    let (uu, ud) = (
        row(u, y.saturating_sub(1), w),
        row(u, (y + 1).min(h - 1), w),
    );
    let (vu, vd) = (
        row(v, y.saturating_sub(1), w),
        row(v, (y + 1).min(h - 1), w),
    );
    // The row with its ends repeated: the neighbours left and right of x are at x and x + 2.
    for (p, r) in [(&mut *pu, ur), (&mut *pv, vr)] {
        p[1..w + 1].copy_from_slice(r);
        p[0] = r[0];
        p[w + 1] = r[w - 1];
    }
    let (ul, urt, vl, vrt) = (&pu[..w], &pu[2..w + 2], &pv[..w], &pv[2..w + 2]);
    let horizontal = &e.horizontal[y * (w + 1)..(y + 1) * (w + 1)];
    let (kl, kr) = (&horizontal[..w], &horizontal[1..w + 1]);
    let (ku, kd) = (row(&e.vertical, y, w), row(&e.vertical, y + 1, w));
    let [c1, c2, a12o, d1, d2, okl, okr, oku, okd] = planes::<FIELDS>(out, w);
    for x in 0..w {
        let (x1, y1) = (dur[x], dvr[x]);
        // Robust weights of the brightness and the gradient constancy terms.
        let r = iz[x] + ix[x] * x1 + iy[x] * y1;
        let wd = k.delta * n1[x] / (n1[x] * r * r + EPS * EPS).sqrt();
        let rx = ixz[x] + ixx[x] * x1 + ixy[x] * y1;
        let ry = iyz[x] + ixy[x] * x1 + iyy[x] * y1;
        let wg = k.gamma / (nx[x] * rx * rx + ny[x] * ry * ry + EPS * EPS).sqrt();
        let (wx, wy) = (wg * nx[x], wg * ny[x]);
        let (gx, gy, gxx, gxy, gyy) = (ix[x], iy[x], ixx[x], ixy[x], iyy[x]);
        let a11 = wd * gx * gx + wx * gxx * gxx + wy * gxy * gxy;
        let a12 = wd * gx * gy + wx * gxx * gxy + wy * gxy * gyy;
        let a22 = wd * gy * gy + wx * gxy * gxy + wy * gyy * gyy;
        let b1 = -(wd * gx * iz[x] + wx * gxx * ixz[x] + wy * gxy * iyz[x]);
        let b2 = -(wd * gy * iz[x] + wx * gxy * ixz[x] + wy * gyy * iyz[x]);
        // The smoothness term's fixed part Σ k_j·(u_j − u) (left, right, up, down) and its
        // diagonal Σ k_j.
        let (a, b) = (ur[x], vr[x]);
        let sum = kl[x] + kr[x] + ku[x] + kd[x];
        let su =
            kl[x] * (ul[x] - a) + kr[x] * (urt[x] - a) + ku[x] * (uu[x] - a) + kd[x] * (ud[x] - a);
        let sv =
            kl[x] * (vl[x] - b) + kr[x] * (vrt[x] - b) + ku[x] * (vu[x] - b) + kd[x] * (vd[x] - b);
        c1[x] = b1 + su;
        c2[x] = b2 + sv;
        a12o[x] = a12;
        d1[x] = a11 + sum;
        d2[x] = a22 + sum;
        okl[x] = kl[x];
        okr[x] = kr[x];
        oku[x] = ku[x];
        okd[x] = kd[x];
    }
}

/// The increments (du, dv) by colour, in the split layout with a zero border: colour c's row y
/// is row y + 1 of an (h+2) × (half(w)+2) array, its entry k at column k + 1. A pass over one
/// colour writes only its own arrays and reads the neighbours, all of the other colour, from
/// the other's: no copy, and rows run in parallel.
struct Increments {
    h: usize,
    w: usize,
    du: [Vec<f32>; 2],
    dv: [Vec<f32>; 2],
}

impl Increments {
    fn new(h: usize, w: usize) -> Self {
        let n = (h + 2) * (half(w) + 2);
        Self {
            h,
            w,
            du: [vec![0.0; n], vec![0.0; n]],
            dv: [vec![0.0; n], vec![0.0; n]],
        }
    }

    /// The increments as plain `[h·w]` planes.
    fn gather(&self, du: &mut [f32], dv: &mut [f32]) {
        let (w, s) = (self.w, half(self.w) + 2);
        du.par_chunks_mut(w)
            .zip(dv.par_chunks_mut(w))
            .enumerate()
            .with_min_len(ROWS)
            .for_each(|(y, (rdu, rdv))| {
                let at = (y + 1) * s + 1;
                for x in 0..w {
                    let c = (x + y) % 2;
                    rdu[x] = self.du[c][at + x / 2];
                    rdv[x] = self.dv[c][at + x / 2];
                }
            });
    }

    /// One over-relaxed Gauss–Seidel pass over the pixels of one colour: they read only pixels
    /// of the other colour, so the result does not depend on the thread count.
    fn sweep(&mut self, colour: usize, coefs: &Coefs, omega: f32) {
        let (h, w) = (self.h, self.w);
        let (m, s) = (half(w), half(w) + 2);
        let [du0, du1] = &mut self.du;
        let [dv0, dv1] = &mut self.dv;
        let (own_du, other_du, own_dv, other_dv) = if colour == 0 {
            (du0, &*du1, dv0, &*dv1)
        } else {
            (du1, &*du0, dv1, &*dv0)
        };
        let coefs = &coefs.colour[colour];
        own_du[s..(h + 1) * s]
            .par_chunks_mut(s)
            .zip(own_dv[s..(h + 1) * s].par_chunks_mut(s))
            .enumerate()
            .with_min_len(ROWS)
            .for_each(|(y, (rdu, rdv))| {
                let o = (colour + y) % 2;
                let n = count(w, o);
                // Pixel x = 2k + o has the other colour's x − 1 and x + 1 at its places
                // k + o − 1 and k + o in this row (columns k + o and k + o + 1 with the border),
                // and x itself at place k in the rows above and below.
                let (du_up, du_at, du_down) = rows3(other_du, y, s);
                let (dv_up, dv_at, dv_down) = rows3(other_dv, y, s);
                let field = |f: usize| &coefs[(y * FIELDS + f) * m..][..n];
                sweep_row(
                    &mut rdu[1..1 + n],
                    &mut rdv[1..1 + n],
                    [
                        &du_at[o..o + n],
                        &du_at[o + 1..o + 1 + n],
                        &du_up[1..1 + n],
                        &du_down[1..1 + n],
                    ],
                    [
                        &dv_at[o..o + n],
                        &dv_at[o + 1..o + 1 + n],
                        &dv_up[1..1 + n],
                        &dv_down[1..1 + n],
                    ],
                    [
                        field(C1),
                        field(C2),
                        field(A12),
                        field(D1),
                        field(D2),
                        field(KL),
                        field(KR),
                        field(KU),
                        field(KD),
                    ],
                    omega,
                );
            });
    }
}

/// The SOR update of one row of one colour: `du`, `dv` its increments, `nu`, `nv` the
/// neighbours' (left, right, up, down), `c` its fields; all slices of one length, so the loop
/// runs without bounds checks and vectorises (the branch is a select).
#[multiversion(targets = "simd")]
fn sweep_row(
    du: &mut [f32],
    dv: &mut [f32],
    nu: [&[f32]; 4],
    nv: [&[f32]; 4],
    c: [&[f32]; FIELDS],
    omega: f32,
) {
    let n = du.len();
    let dv = &mut dv[..n];
    let [ul, ur, uu, ud] = nu.map(|s| &s[..n]);
    let [vl, vr, vu, vd] = nv.map(|s| &s[..n]);
    let [c1, c2, a12, d1, d2, kl, kr, ku, kd] = c.map(|s| &s[..n]);
    for k in 0..n {
        let su = kl[k] * ul[k] + kr[k] * ur[k] + ku[k] * uu[k] + kd[k] * ud[k];
        let sv = kl[k] * vl[k] + kr[k] * vr[k] + ku[k] * vu[k] + kd[k] * vd[k];
        // Gauss–Seidel within the pixel: dv's update uses the new du. A pixel without any
        // equation (zero diagonal) keeps its increment.
        let nu = (c1[k] - a12[k] * dv[k] + su) / d1[k];
        let x = du[k] + omega * (nu - du[k]);
        du[k] = if d1[k] > 0.0 { x } else { du[k] };
        let nv = (c2[k] - a12[k] * du[k] + sv) / d2[k];
        let y = dv[k] + omega * (nv - dv[k]);
        dv[k] = if d2[k] > 0.0 { y } else { dv[k] };
    }
}

/// Rows `r`, `r + 1`, `r + 2` of `a`, rows of `s` values.
fn rows3(a: &[f32], r: usize, s: usize) -> (&[f32], &[f32], &[f32]) {
    (
        &a[r * s..(r + 1) * s],
        &a[(r + 1) * s..(r + 2) * s],
        &a[(r + 2) * s..(r + 3) * s],
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flow::refine::{linearise, reference};
    use crate::report::refine_bench::pair;

    /// On a realistic pair (a texture and a smoothly warped copy, a start off by up to a
    /// pixel) the solver gives the straightforward reference's flow to float rounding.
    #[test]
    fn matches_the_reference_solver() {
        let (h, w) = (96, 128);
        let p = pair(h, w).unwrap();
        let grey = |img: &crate::types::Image| -> Vec<f32> {
            img.plane(0).iter().map(|x| 255.0 * x).collect()
        };
        let (i0, i1) = (grey(&p.frame1), grey(&p.frame2));
        let k = Weights {
            alpha: 20.0,
            delta: 5.0,
            gamma: 10.0,
            fixed_point_iters: 5,
            sor_iters: 5,
            omega: 1.6,
        };
        let terms = linearise::terms(&i0, &i1, p.start.u(), p.start.v(), h, w, 5.0);
        let (mut u, mut v) = (p.start.u().to_vec(), p.start.v().to_vec());
        let (mut ru, mut rv) = (u.clone(), v.clone());
        solve(&terms, &mut u, &mut v, h, w, &k);
        reference::solve(&terms, &mut ru, &mut rv, h, w, &k);
        let moved = u.iter().zip(p.start.u()).map(|(a, b)| (a - b).abs());
        assert!(
            moved.fold(0.0f32, f32::max) > 0.1,
            "the solver did not move"
        );
        let diff = u
            .iter()
            .zip(&ru)
            .chain(v.iter().zip(&rv))
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        assert!(
            diff < 1e-4,
            "largest difference to the reference: {diff} px"
        );
    }
}
