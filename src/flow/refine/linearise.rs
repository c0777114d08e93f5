//! The linearised data terms of the variational refinement (brightness and gradient constancy,
//! Brox et al. 2004, normalised as in DeepFlow): frame 2 is warped once by the current flow and
//! every pixel gets the coefficients of its two constancy assumptions in the unknown increment
//! (du, dv).

use rayon::prelude::*;

/// Per-pixel coefficients at one scale, each `[H·W]`, intensities in 8-bit units.
///
/// Brightness constancy, linearised: `Iz + Ix·du + Iy·dv ≈ 0`; gradient constancy:
/// `Ixz + Ixx·du + Ixy·dv ≈ 0` and `Iyz + Ixy·du + Iyy·dv ≈ 0`. `n1`, `nx`, `ny` are the
/// normalisations 1 / (|gradient|² + ζ²) of the three constraints, zero where the warped
/// position leaves the frame (no data there: smoothness fills it in).
pub struct Terms {
    pub ix: Vec<f32>,
    pub iy: Vec<f32>,
    pub iz: Vec<f32>,
    pub ixx: Vec<f32>,
    pub ixy: Vec<f32>,
    pub iyy: Vec<f32>,
    pub ixz: Vec<f32>,
    pub iyz: Vec<f32>,
    pub n1: Vec<f32>,
    pub nx: Vec<f32>,
    pub ny: Vec<f32>,
    /// The local smoothness weight exp(−κ·|∇I|/255) of each pixel (DeepFlow's α(x)): the flow
    /// may change across an image edge, where a moving object's boundary is likely to lie.
    pub smooth: Vec<f32>,
}

/// ζ of the normalisation: keeps flat regions (gradient ≈ 0) from dividing by zero; in 8-bit
/// units it matters only where the gradient is below about 0.1 grey level per pixel.
const ZETA: f32 = 0.1;

/// The terms of `i0` and `i1` (`[h·w]` grey planes, 8-bit units) around the flow `(u, v)`, with
/// the local smoothness weight of `kappa` (κ; 0: the same weight everywhere).
pub fn terms(
    i0: &[f32],
    i1: &[f32],
    u: &[f32],
    v: &[f32],
    h: usize,
    w: usize,
    kappa: f32,
) -> Terms {
    let n = h * w;
    let (warped, inside) = warp(i1, u, v, h, w);
    let (i0x, i0y) = (deriv_x(i0, h, w), deriv_y(i0, h, w));
    let (i1x, i1y) = (deriv_x(&warped, h, w), deriv_y(&warped, h, w));
    // First derivatives of the data term: the mean of both frames (the warped second frame
    // alone is noisier and biased where the warp is wrong).
    let ix: Vec<f32> = i0x.iter().zip(&i1x).map(|(a, b)| 0.5 * (a + b)).collect();
    let iy: Vec<f32> = i0y.iter().zip(&i1y).map(|(a, b)| 0.5 * (a + b)).collect();
    let iz: Vec<f32> = warped.iter().zip(i0).map(|(b, a)| b - a).collect();
    let ixx = deriv_x(&ix, h, w);
    let ixy = {
        let a = deriv_y(&ix, h, w);
        let b = deriv_x(&iy, h, w);
        a.iter()
            .zip(&b)
            .map(|(a, b)| 0.5 * (a + b))
            .collect::<Vec<f32>>()
    };
    let iyy = deriv_y(&iy, h, w);
    let ixz: Vec<f32> = i1x.iter().zip(&i0x).map(|(b, a)| b - a).collect();
    let iyz: Vec<f32> = i1y.iter().zip(&i0y).map(|(b, a)| b - a).collect();
    let z2 = ZETA * ZETA;
    let mut n1 = vec![0.0f32; n];
    let mut nx = vec![0.0f32; n];
    let mut ny = vec![0.0f32; n];
    for i in 0..n {
        if inside[i] {
            n1[i] = 1.0 / (ix[i] * ix[i] + iy[i] * iy[i] + z2);
            nx[i] = 1.0 / (ixx[i] * ixx[i] + ixy[i] * ixy[i] + z2);
            ny[i] = 1.0 / (ixy[i] * ixy[i] + iyy[i] * iyy[i] + z2);
        }
    }
    let smooth = ix
        .iter()
        .zip(&iy)
        .map(|(x, y)| (-kappa * (x * x + y * y).sqrt() / 255.0).exp())
        .collect();
    Terms {
        smooth,
        ix,
        iy,
        iz,
        ixx,
        ixy,
        iyy,
        ixz,
        iyz,
        n1,
        nx,
        ny,
    }
}

/// `img` sampled bilinearly at `(x + u, y + v)` (borders clamped), and whether that point lies
/// inside the frame; rows in parallel.
pub fn warp(img: &[f32], u: &[f32], v: &[f32], h: usize, w: usize) -> (Vec<f32>, Vec<bool>) {
    let mut out = vec![0.0f32; h * w];
    let mut inside = vec![false; h * w];
    let (wm, hm) = ((w - 1) as f32, (h - 1) as f32);
    out.par_chunks_mut(w)
        .zip(inside.par_chunks_mut(w))
        .enumerate()
        .for_each(|(y, (out, inside))| {
            for x in 0..w {
                let i = y * w + x;
                let sx = x as f32 + u[i];
                let sy = y as f32 + v[i];
                inside[x] = sx.is_finite()
                    && sy.is_finite()
                    && (0.0..=wm).contains(&sx)
                    && (0.0..=hm).contains(&sy);
                let (cx, cy) = (sx.clamp(0.0, wm), sy.clamp(0.0, hm));
                let (cx, cy) = if cx.is_finite() && cy.is_finite() {
                    (cx, cy)
                } else {
                    (x as f32, y as f32)
                };
                let (x0, y0) = (cx.floor() as usize, cy.floor() as usize);
                let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
                let (fx, fy) = (cx - x0 as f32, cy - y0 as f32);
                let top = img[y0 * w + x0] * (1.0 - fx) + img[y0 * w + x1] * fx;
                let bottom = img[y1 * w + x0] * (1.0 - fx) + img[y1 * w + x1] * fx;
                out[x] = top * (1.0 - fy) + bottom * fy;
            }
        });
    (out, inside)
}

/// The five-point derivative (1, −8, 0, 8, −1) / 12 along x, borders replicated; rows in
/// parallel.
pub fn deriv_x(p: &[f32], h: usize, w: usize) -> Vec<f32> {
    let mut out = vec![0.0f32; h * w];
    let at = |x: isize| x.clamp(0, w as isize - 1) as usize;
    out.par_chunks_mut(w).enumerate().for_each(|(y, out)| {
        let row = &p[y * w..(y + 1) * w];
        for x in 0..w as isize {
            out[x as usize] = (row[at(x - 2)] - 8.0 * row[at(x - 1)] + 8.0 * row[at(x + 1)]
                - row[at(x + 2)])
                / 12.0;
        }
    });
    out
}

/// The five-point derivative along y, borders replicated; rows in parallel.
pub fn deriv_y(p: &[f32], h: usize, w: usize) -> Vec<f32> {
    let mut out = vec![0.0f32; h * w];
    let at = |y: isize| y.clamp(0, h as isize - 1) as usize;
    out.par_chunks_mut(w).enumerate().for_each(|(y, out)| {
        let y = y as isize;
        let (a, b, c, d) = (at(y - 2), at(y - 1), at(y + 1), at(y + 2));
        let row = |r: usize| &p[r * w..(r + 1) * w];
        let (a, b, c, d) = (row(a), row(b), row(c), row(d));
        for x in 0..w {
            out[x] = (a[x] - 8.0 * b[x] + 8.0 * c[x] - d[x]) / 12.0;
        }
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The five-point stencil is exact on cubics away from the border.
    #[test]
    fn derivatives_are_exact_on_cubics() {
        let (h, w) = (9, 11);
        let f = |x: f32, y: f32| 0.5 * x * x * x - 2.0 * x * y + 3.0 * y * y - y * y * y / 7.0;
        let p: Vec<f32> = (0..h * w)
            .map(|i| f((i % w) as f32, (i / w) as f32))
            .collect();
        let (dx, dy) = (deriv_x(&p, h, w), deriv_y(&p, h, w));
        for y in 2..h - 2 {
            for x in 2..w - 2 {
                let (xf, yf) = (x as f32, y as f32);
                assert!((dx[y * w + x] - (1.5 * xf * xf - 2.0 * yf)).abs() < 1e-3);
                assert!(
                    (dy[y * w + x] - (-2.0 * xf + 6.0 * yf - 3.0 * yf * yf / 7.0)).abs() < 1e-3
                );
            }
        }
    }

    /// Warping a linear ramp by a constant sub-pixel shift adds the shift times the slope, and
    /// points pushed out of the frame are marked outside.
    #[test]
    fn warp_of_a_ramp_is_exact_and_marks_the_outside() {
        let (h, w) = (5, 8);
        let p: Vec<f32> = (0..h * w)
            .map(|i| 2.0 * (i % w) as f32 + (i / w) as f32)
            .collect();
        let u = vec![0.25f32; h * w];
        let v = vec![-0.5f32; h * w];
        let (out, inside) = warp(&p, &u, &v, h, w);
        for y in 1..h {
            for x in 0..w - 1 {
                let i = y * w + x;
                assert!((out[i] - (p[i] + 0.5 - 0.5)).abs() < 1e-5);
                assert!(inside[i]);
            }
        }
        assert!(
            !inside[3],
            "row 0 moved up by half a pixel leaves the frame"
        );
        assert!(
            !inside[w - 1 + w],
            "the last column moved right leaves the frame"
        );
    }

    /// Where frame 2 is frame 1 moved by exactly the flow, the brightness residual is zero.
    #[test]
    fn residual_vanishes_for_the_true_flow() {
        let (h, w) = (16, 16);
        let f = |x: f32, y: f32| 100.0 + 40.0 * (0.3 * x).sin() * (0.2 * y).cos();
        let i0: Vec<f32> = (0..h * w)
            .map(|i| f((i % w) as f32, (i / w) as f32))
            .collect();
        let i1: Vec<f32> = (0..h * w)
            .map(|i| f((i % w) as f32 - 1.0, (i / w) as f32 - 2.0))
            .collect();
        let t = terms(&i0, &i1, &vec![1.0; h * w], &vec![2.0; h * w], h, w, 0.0);
        for y in 0..h - 2 {
            for x in 0..w - 1 {
                assert!(t.iz[y * w + x].abs() < 1e-3, "{}", t.iz[y * w + x]);
            }
        }
    }
}
