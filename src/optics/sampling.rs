//! Note S2 PSF measurement: box-integrating the fine diffraction intensity into sensor pixels,
//! and the focal-spot radius (83.8 % encircled energy, the Airy first-zero radius).

use super::propagate::Fine;

/// Energy fraction collected by an odd `p`×`p` grid of square pixels of pitch `pixel_m`
/// centred on the reference point (fine sample u = 0), `[p, p]` row-major.
///
/// Each fine sample stands for a `dx`×`dy` cell of constant intensity; a pixel collects the
/// exact overlap area of every cell, so energy is conserved (better than supersampling for a
/// spot smaller than one pixel). Values are fractions of the whole fine window's energy.
pub(crate) fn integrate_pixels(fine: &Fine, pixel_m: f64, p: usize) -> Vec<f64> {
    let wx = weights(fine.n, fine.dx_m, pixel_m, p);
    let wy = weights(fine.n, fine.dy_m, pixel_m, p);
    let mut out = vec![0f64; p * p];
    for (a, row_w) in wy.iter().enumerate() {
        for &(i, wyi) in row_w {
            let line = &fine.data[i * fine.n..(i + 1) * fine.n];
            for (b, col_w) in wx.iter().enumerate() {
                let s: f64 = col_w.iter().map(|&(j, w)| w * line[j]).sum();
                out[a * p + b] += wyi * s;
            }
        }
    }
    let total = fine.total.max(f64::MIN_POSITIVE);
    out.iter_mut().for_each(|v| *v /= total);
    out
}

/// For each of `p` pixels along one axis, the fine samples it overlaps and the fraction of
/// each sample's cell inside the pixel.
fn weights(n: usize, d: f64, pixel: f64, p: usize) -> Vec<Vec<(usize, f64)>> {
    let h = (n / 2) as f64;
    (0..p)
        .map(|b| {
            let lo = (b as f64 - (p / 2) as f64 - 0.5) * pixel;
            let hi = lo + pixel;
            // Fine cell j covers [(j − h − ½) d, (j − h + ½) d].
            let j0 = ((lo / d + h - 0.5).floor().max(0.0)) as usize;
            let j1 = ((hi / d + h + 0.5).ceil().min(n as f64 - 1.0)).max(0.0) as usize;
            (j0..=j1)
                .filter_map(|j| {
                    let c_lo = (j as f64 - h - 0.5) * d;
                    let ov = (hi.min(c_lo + d) - lo.max(c_lo)) / d;
                    (ov > 0.0).then_some((j, ov))
                })
                .collect()
        })
        .collect()
}

/// Intensity centroid (m) of the fine window relative to the reference point, `(x, y)`.
pub(crate) fn centroid(fine: &Fine) -> (f64, f64) {
    let h = (fine.n / 2) as f64;
    let (mut sx, mut sy) = (0.0, 0.0);
    for (i, line) in fine.data.chunks(fine.n).enumerate() {
        let row: f64 = line.iter().sum();
        let mx: f64 = line.iter().enumerate().map(|(j, &v)| j as f64 * v).sum();
        sy += (i as f64 - h) * row;
        sx += mx - h * row;
    }
    let t = fine.total.max(f64::MIN_POSITIVE);
    (sx / t * fine.dx_m, sy / t * fine.dy_m)
}

/// Radius (m) around `(cx, cy)` enclosing `frac` of the window's energy, from a radial
/// histogram with bins a quarter of the finer pitch, linearly interpolated within a bin.
pub(crate) fn encircled_radius(fine: &Fine, (cx, cy): (f64, f64), frac: f64) -> f64 {
    let bin = fine.dx_m.min(fine.dy_m) / 4.0;
    let h = (fine.n / 2) as f64;
    let rmax = h * (fine.dx_m.hypot(fine.dy_m)) + cx.hypot(cy);
    let nb = (rmax / bin).ceil() as usize + 2;
    let mut hist = vec![0f64; nb];
    for (i, line) in fine.data.chunks(fine.n).enumerate() {
        let dy = (i as f64 - h) * fine.dy_m - cy;
        for (j, &v) in line.iter().enumerate() {
            let dx = (j as f64 - h) * fine.dx_m - cx;
            hist[((dx.hypot(dy) / bin) as usize).min(nb - 1)] += v;
        }
    }
    let target = frac * fine.total;
    let mut acc = 0.0;
    for (b, &e) in hist.iter().enumerate() {
        if acc + e >= target && e > 0.0 {
            return (b as f64 + (target - acc) / e) * bin;
        }
        acc += e;
    }
    nb as f64 * bin
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fine_from(n: usize, d: f64, f: impl Fn(f64, f64) -> f64) -> Fine {
        let h = (n / 2) as f64;
        let data: Vec<f64> = (0..n * n)
            .map(|k| f(((k % n) as f64 - h) * d, ((k / n) as f64 - h) * d))
            .collect();
        let total = data.iter().sum();
        Fine {
            n,
            dx_m: d,
            dy_m: d,
            data,
            total,
            peak_ratio: 1.0,
        }
    }

    #[test]
    fn pixels_conserve_energy_and_centre() {
        let fine = fine_from(64, 0.3, |x, y| (-(x * x + y * y) / 2.0).exp());
        let px = integrate_pixels(&fine, 2.2, 7);
        let s: f64 = px.iter().sum();
        assert!((s - 1.0).abs() < 1e-6, "{s}");
        assert_eq!(px.iter().cloned().fold(0.0, f64::max), px[3 * 7 + 3]);
        assert!((px[3 * 7 + 2] - px[3 * 7 + 4]).abs() < 1e-12);
        let (cx, cy) = centroid(&fine);
        assert!(cx.abs() < 1e-9 && cy.abs() < 1e-9);
    }

    #[test]
    fn encircled_radius_of_a_uniform_disk() {
        // Uniform disk of radius 5: 83.8 % of the energy lies within 5 √0.838.
        let fine = fine_from(256, 0.05, |x, y| (x * x + y * y <= 25.0) as u8 as f64);
        let r = encircled_radius(&fine, (0.0, 0.0), 0.838);
        assert!((r - 5.0 * 0.838f64.sqrt()).abs() < 0.03, "{r}");
    }
}
