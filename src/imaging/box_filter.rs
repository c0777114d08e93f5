//! Box filtering by summed-area tables (f64, so the cost does not depend on the radius):
//! the mean over the (2r + 1)² box around each pixel, clipped at the border, skipping unknown
//! values; the minimum over the box (a grey erosion, separable); and the square dilation of a
//! mask.

/// The mean of the known (finite) values in the `(2r + 1)²` box around each pixel of a
/// `[h, w]` plane, the box clipped at the border, and how many values it averaged; NaN where
/// the box holds no known value. Summed-area tables in f64, so the cost does not depend on
/// `r`.
pub fn box_mean(p: &[f32], w: usize, h: usize, r: usize) -> (Vec<f32>, Vec<u32>) {
    let stride = w + 1;
    let mut sum = vec![0.0f64; (h + 1) * stride];
    let mut count = vec![0u32; (h + 1) * stride];
    for y in 0..h {
        for x in 0..w {
            let v = p[y * w + x];
            let (s, c) = if v.is_finite() {
                (v as f64, 1)
            } else {
                (0.0, 0)
            };
            let i = (y + 1) * stride + x + 1;
            sum[i] = s + sum[i - 1] + sum[i - stride] - sum[i - stride - 1];
            count[i] = c + count[i - 1] + count[i - stride] - count[i - stride - 1];
        }
    }
    let mut out = vec![f32::NAN; w * h];
    let mut counts = vec![0u32; w * h];
    for y in 0..h {
        let (y0, y1) = (y.saturating_sub(r), (y + r + 1).min(h));
        for x in 0..w {
            let (x0, x1) = (x.saturating_sub(r), (x + r + 1).min(w));
            let at = |yy: usize, xx: usize| yy * stride + xx;
            let n = count[at(y1, x1)] + count[at(y0, x0)] - count[at(y0, x1)] - count[at(y1, x0)];
            counts[y * w + x] = n;
            if n > 0 {
                let s = sum[at(y1, x1)] + sum[at(y0, x0)] - sum[at(y0, x1)] - sum[at(y1, x0)];
                out[y * w + x] = (s / n as f64) as f32;
            }
        }
    }
    (out, counts)
}

/// The minimum over the `(2r + 1)²` box around each pixel of a `[h, w]` plane, the box clipped
/// at the border (a grey erosion by a square; separable: rows, then columns). NaN counts as
/// unknown and is skipped; a box of unknown values gives NaN.
pub fn box_min(p: &[f32], w: usize, h: usize, r: usize) -> Vec<f32> {
    // The least known value of an iterator, NaN when it holds none.
    fn least(values: impl Iterator<Item = f32>) -> f32 {
        values
            .filter(|v| !v.is_nan())
            .reduce(f32::min)
            .unwrap_or(f32::NAN)
    }
    let mut rows = vec![f32::NAN; w * h];
    for y in 0..h {
        let row = &p[y * w..(y + 1) * w];
        for x in 0..w {
            let (x0, x1) = (x.saturating_sub(r), (x + r + 1).min(w));
            rows[y * w + x] = least(row[x0..x1].iter().copied());
        }
    }
    let mut out = vec![f32::NAN; w * h];
    for y in 0..h {
        let (y0, y1) = (y.saturating_sub(r), (y + r + 1).min(h));
        for x in 0..w {
            out[y * w + x] = least((y0..y1).map(|yy| rows[yy * w + x]));
        }
    }
    out
}

/// The pixels within `r` (a square neighbourhood) of a `true` pixel of a `[h, w]` mask.
pub fn dilate(mask: &[bool], w: usize, h: usize, r: usize) -> Vec<bool> {
    let ones: Vec<f32> = mask.iter().map(|&m| if m { 1.0 } else { 0.0 }).collect();
    box_mean(&ones, w, h, r)
        .0
        .iter()
        .map(|&v| v > 0.0)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_min_matches_a_direct_minimum_and_skips_unknown_values() {
        let (w, h) = (9, 6);
        let mut p: Vec<f32> = (0..w * h).map(|i| ((i * 37) % 11) as f32 - 3.0).collect();
        p[10] = f32::NAN;
        for r in [0, 1, 2, 5] {
            let got = box_min(&p, w, h, r);
            for y in 0..h {
                for x in 0..w {
                    let mut m = f32::INFINITY;
                    for yy in y.saturating_sub(r)..(y + r + 1).min(h) {
                        for xx in x.saturating_sub(r)..(x + r + 1).min(w) {
                            if !p[yy * w + xx].is_nan() {
                                m = m.min(p[yy * w + xx]);
                            }
                        }
                    }
                    let want = if m.is_finite() { m } else { f32::NAN };
                    let g = got[y * w + x];
                    assert!(
                        g == want || (g.is_nan() && want.is_nan()),
                        "r {r} at ({x}, {y})"
                    );
                }
            }
        }
        // A box of nothing but unknown values stays unknown.
        assert!(box_min(&[f32::NAN; 4], 2, 2, 1).iter().all(|v| v.is_nan()));
    }

    #[test]
    fn box_mean_matches_a_direct_sum_and_skips_unknown_values() {
        let (w, h) = (7, 5);
        let mut p: Vec<f32> = (0..w * h).map(|i| ((i * 37) % 11) as f32).collect();
        p[8] = f32::NAN;
        let (got, counts) = box_mean(&p, w, h, 2);
        for y in 0..h {
            for x in 0..w {
                let (mut s, mut n) = (0.0, 0);
                for yy in y.saturating_sub(2)..(y + 3).min(h) {
                    for xx in x.saturating_sub(2)..(x + 3).min(w) {
                        if p[yy * w + xx].is_finite() {
                            s += p[yy * w + xx] as f64;
                            n += 1;
                        }
                    }
                }
                assert!(
                    (got[y * w + x] as f64 - s / n as f64).abs() < 1e-5,
                    "({x}, {y})"
                );
                assert_eq!(counts[y * w + x], n, "({x}, {y})");
            }
        }
        assert!(
            box_mean(&[f32::NAN; 4], 2, 2, 1)
                .0
                .iter()
                .all(|v| v.is_nan())
        );
        let d = dilate(&[false, false, false, true, false, false], 6, 1, 1);
        assert_eq!(d, [false, false, true, true, true, false]);
    }
}
