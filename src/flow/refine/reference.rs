//! The straightforward solver the optimised one (`solver`) is checked against (tests only): the
//! same energy and iteration as `solver` describes, one pixel at a time with its neighbours
//! looked up, every coefficient recomputed in each sweep and the increments copied before it.

use rayon::prelude::*;

use super::linearise::Terms;
use super::solver::{EPS, Weights};

/// Refines `(u, v)` (`[h·w]` each) in place with the linearised `terms`.
pub fn solve(t: &Terms, u: &mut [f32], v: &mut [f32], h: usize, w: usize, k: &Weights) {
    let n = h * w;
    let mut du = vec![0.0f32; n];
    let mut dv = vec![0.0f32; n];
    // Per pixel: the 2×2 system A·(du, dv) = b of the data terms.
    let mut a11 = vec![0.0f32; n];
    let mut a12 = vec![0.0f32; n];
    let mut a22 = vec![0.0f32; n];
    let mut b1 = vec![0.0f32; n];
    let mut b2 = vec![0.0f32; n];
    // Smoothness weights on the edge to the right (`sh`) and below (`sv`) of each pixel.
    let mut sh = vec![0.0f32; n];
    let mut sv = vec![0.0f32; n];
    for _ in 0..k.fixed_point_iters {
        data_system(
            t, &du, &dv, k, &mut a11, &mut a12, &mut a22, &mut b1, &mut b2,
        );
        smoothness(u, v, &du, &dv, h, w, &t.smooth, k.alpha, &mut sh, &mut sv);
        let sys = System {
            a11: &a11,
            a12: &a12,
            a22: &a22,
            b1: &b1,
            b2: &b2,
            sh: &sh,
            sv: &sv,
            u,
            v,
            h,
            w,
            omega: k.omega,
        };
        for _ in 0..k.sor_iters {
            for colour in 0..2 {
                sys.sweep(colour, &mut du, &mut dv);
            }
        }
    }
    for i in 0..n {
        u[i] += du[i];
        v[i] += dv[i];
    }
}

/// The data terms' robust weights at the current increment and the resulting 2×2 systems.
#[allow(clippy::too_many_arguments)]
fn data_system(
    t: &Terms,
    du: &[f32],
    dv: &[f32],
    k: &Weights,
    a11: &mut [f32],
    a12: &mut [f32],
    a22: &mut [f32],
    b1: &mut [f32],
    b2: &mut [f32],
) {
    for i in 0..du.len() {
        let (x, y) = (du[i], dv[i]);
        let r = t.iz[i] + t.ix[i] * x + t.iy[i] * y;
        let wd = k.delta * t.n1[i] / (t.n1[i] * r * r + EPS * EPS).sqrt();
        let rx = t.ixz[i] + t.ixx[i] * x + t.ixy[i] * y;
        let ry = t.iyz[i] + t.ixy[i] * x + t.iyy[i] * y;
        let wg = k.gamma / (t.nx[i] * rx * rx + t.ny[i] * ry * ry + EPS * EPS).sqrt();
        let (wx, wy) = (wg * t.nx[i], wg * t.ny[i]);
        a11[i] = wd * t.ix[i] * t.ix[i] + wx * t.ixx[i] * t.ixx[i] + wy * t.ixy[i] * t.ixy[i];
        a12[i] = wd * t.ix[i] * t.iy[i] + wx * t.ixx[i] * t.ixy[i] + wy * t.ixy[i] * t.iyy[i];
        a22[i] = wd * t.iy[i] * t.iy[i] + wx * t.ixy[i] * t.ixy[i] + wy * t.iyy[i] * t.iyy[i];
        b1[i] = -(wd * t.ix[i] * t.iz[i] + wx * t.ixx[i] * t.ixz[i] + wy * t.ixy[i] * t.iyz[i]);
        b2[i] = -(wd * t.iy[i] * t.iz[i] + wx * t.ixy[i] * t.ixz[i] + wy * t.iyy[i] * t.iyz[i]);
    }
}

/// The smoothness term's robust weight α·Ψ′ at each pixel (forward differences of u + du and
/// v + dv), averaged onto the edges between neighbours; edges leaving the frame weigh zero.
#[allow(clippy::too_many_arguments)]
fn smoothness(
    u: &[f32],
    v: &[f32],
    du: &[f32],
    dv: &[f32],
    h: usize,
    w: usize,
    local: &[f32],
    alpha: f32,
    sh: &mut [f32],
    sv: &mut [f32],
) {
    let mut psi = vec![0.0f32; h * w];
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let (uu, vv) = (u[i] + du[i], v[i] + dv[i]);
            let (mut g, j) = (0.0f32, if x + 1 < w { i + 1 } else { i });
            g += (u[j] + du[j] - uu).powi(2) + (v[j] + dv[j] - vv).powi(2);
            let j = if y + 1 < h { i + w } else { i };
            g += (u[j] + du[j] - uu).powi(2) + (v[j] + dv[j] - vv).powi(2);
            psi[i] = alpha * local[i] / (g + EPS * EPS).sqrt();
        }
    }
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            sh[i] = if x + 1 < w {
                0.5 * (psi[i] + psi[i + 1])
            } else {
                0.0
            };
            sv[i] = if y + 1 < h {
                0.5 * (psi[i] + psi[i + w])
            } else {
                0.0
            };
        }
    }
}

/// The linear system of one fixed-point iteration.
struct System<'a> {
    a11: &'a [f32],
    a12: &'a [f32],
    a22: &'a [f32],
    b1: &'a [f32],
    b2: &'a [f32],
    sh: &'a [f32],
    sv: &'a [f32],
    u: &'a [f32],
    v: &'a [f32],
    h: usize,
    w: usize,
    omega: f32,
}

impl System<'_> {
    /// One over-relaxed Gauss–Seidel pass over the pixels of one colour ((x + y) mod 2): they
    /// read only pixels of the other colour, so rows run in parallel and the result does not
    /// depend on the thread count.
    fn sweep(&self, colour: usize, du: &mut [f32], dv: &mut [f32]) {
        let (h, w) = (self.h, self.w);
        let (pdu, pdv) = (du.to_vec(), dv.to_vec());
        du.par_chunks_mut(w)
            .zip(dv.par_chunks_mut(w))
            .enumerate()
            .for_each(|(y, (rdu, rdv))| {
                let mut x = (colour + y) % 2;
                while x < w {
                    let i = y * w + x;
                    // Neighbours: (index, edge weight).
                    let nb = [
                        (x > 0).then(|| (i - 1, self.sh[i - 1])),
                        (x + 1 < w).then(|| (i + 1, self.sh[i])),
                        (y > 0).then(|| (i - w, self.sv[i - w])),
                        (y + 1 < h).then(|| (i + w, self.sv[i])),
                    ];
                    let (mut sum_w, mut su, mut sv) = (0.0f32, 0.0f32, 0.0f32);
                    for (j, k) in nb.into_iter().flatten() {
                        sum_w += k;
                        su += k * (self.u[j] + pdu[j] - self.u[i]);
                        sv += k * (self.v[j] + pdv[j] - self.v[i]);
                    }
                    let d1 = self.a11[i] + sum_w;
                    if d1 > 0.0 {
                        let nu = (self.b1[i] - self.a12[i] * rdv[x] + su) / d1;
                        rdu[x] += self.omega * (nu - rdu[x]);
                    }
                    let d2 = self.a22[i] + sum_w;
                    if d2 > 0.0 {
                        let nv = (self.b2[i] - self.a12[i] * rdu[x] + sv) / d2;
                        rdv[x] += self.omega * (nv - rdv[x]);
                    }
                    x += 2;
                }
            });
    }
}
