//! Calibration of the array from a dot-grid frame (Note S3, Fig. S3c): dots found by threshold,
//! connected components and intensity-weighted centroids; matched to the known grid through
//! the nominal lens model; per lens, polynomials f_x, f_y from object points (stitched image)
//! to distorted points (raw sensor), their order chosen by held-out error.

use serde::{Deserialize, Serialize};

use super::layout::ArrayLayout;
use super::polyfit::{Poly2, terms};
use super::render::{nominal_sensor_position, sensor_to_tile};
use crate::error::{Error, Result};
use crate::imaging::box_filter::box_mean;
use crate::types::Image;

/// One lens's fitted map and its accuracy.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LensCalibration {
    pub fx: Poly2,
    pub fy: Poly2,
    pub dots: usize,
    /// Reprojection error on the grid dots, pixels.
    pub rms_px: f64,
    pub max_px: f64,
    /// Held-out RMS of each order tried, `(order, rms)`.
    pub held_out: Vec<(usize, f64)>,
}

/// `calib.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Calibration {
    pub layout: ArrayLayout,
    pub dots_per_side: usize,
    pub lenses: Vec<LensCalibration>,
}

/// A dot found in the raw frame.
#[derive(Clone, Copy, Debug)]
pub struct Dot {
    pub lens: usize,
    pub x: f64,
    pub y: f64,
    pub area: usize,
}

/// The plane to find dots in: green for a colour frame (the design wavelength's channel, the
/// sharpest through the metalens), smoothed by a 5×5 box so that sensor noise neither splits a
/// dot nor makes spurious ones.
fn grey(raw: &Image) -> Vec<f32> {
    let (c, h, w) = raw.shape();
    let p = raw.plane(if c >= 3 { 1 } else { 0 });
    let r = 2usize;
    let mut tmp = vec![0.0f32; h * w];
    for y in 0..h {
        for x in 0..w {
            let (a, b) = (x.saturating_sub(r), (x + r).min(w - 1));
            tmp[y * w + x] = p[y * w + a..=y * w + b].iter().sum::<f32>() / (b - a + 1) as f32;
        }
    }
    let mut out = vec![0.0f32; h * w];
    for y in 0..h {
        let (a, b) = (y.saturating_sub(r), (y + r).min(h - 1));
        for x in 0..w {
            out[y * w + x] = (a..=b).map(|yy| tmp[yy * w + x]).sum::<f32>() / (b - a + 1) as f32;
        }
    }
    out
}

/// Finds the dark dots of each lens's sub-image: pixels darker than their 31×31 neighbourhood
/// by a fifth of the sub-image's contrast (background: 90th percentile, dots: 1st), grouped into
/// 8-connected components, centroids weighted by darkness.
pub fn detect_dots(layout: &ArrayLayout, raw: &Image) -> Result<Vec<Dot>> {
    let [h, w] = layout.sensor;
    if (raw.height(), raw.width()) != (h, w) {
        return Err(Error::shape(
            "raw frame",
            format!("{w}x{h} (the layout's sensor)"),
            format!("{}x{}", raw.width(), raw.height()),
        ));
    }
    let g = grey(raw);
    let owner: Vec<i16> = (0..h * w)
        .map(|i| {
            sensor_to_tile(layout, (i % w) as f64, (i / w) as f64).map_or(-1, |(l, _, _)| l as i16)
        })
        .collect();
    let local = box_mean(&g, w, h, 15).0;
    let mut dots = Vec::new();
    for lens in 0..layout.lenses.len() {
        let mut vals: Vec<f32> = (0..h * w)
            .filter(|&i| owner[i] == lens as i16)
            .map(|i| g[i])
            .collect();
        if vals.is_empty() {
            continue;
        }
        vals.sort_by(|a, b| a.total_cmp(b));
        let (dark, bg) = (vals[vals.len() / 100], vals[vals.len() * 9 / 10]);
        if bg - dark < 1e-3 {
            continue;
        }
        // Adaptive threshold: a dot pixel is darker than its neighbourhood by a fifth of the
        // sub-image's contrast. A global threshold fails where the PSF blurs the sub-image's
        // border into the dark surround.
        let margin = 0.2 * (bg - dark);
        let is_dot = |i: usize| {
            owner[i] == lens as i16 && g[i] < local[i] - margin && local[i] > dark + margin
        };
        let mut seen = vec![false; h * w];
        for start in 0..h * w {
            if seen[start] || !is_dot(start) {
                continue;
            }
            let (mut sw, mut sx, mut sy, mut area) = (0.0f64, 0.0f64, 0.0f64, 0usize);
            let mut stack = vec![start];
            seen[start] = true;
            while let Some(p) = stack.pop() {
                let (px, py) = (p % w, p / w);
                let wgt = (bg - g[p]).max(0.0) as f64;
                sw += wgt;
                sx += wgt * px as f64;
                sy += wgt * py as f64;
                area += 1;
                for dy in -1i64..=1 {
                    for dx in -1i64..=1 {
                        let (nx, ny) = (px as i64 + dx, py as i64 + dy);
                        if nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                            continue;
                        }
                        let q = ny as usize * w + nx as usize;
                        if !seen[q] && is_dot(q) {
                            seen[q] = true;
                            stack.push(q);
                        }
                    }
                }
            }
            if area >= 3 && sw > 0.0 {
                dots.push(Dot {
                    lens,
                    x: sx / sw,
                    y: sy / sw,
                    area,
                });
            }
        }
    }
    Ok(dots)
}

fn held_out_rms(obj: &[(f64, f64)], xs: &[f64], ys: &[f64], order: usize) -> Option<f64> {
    let folds = 5;
    let (mut se, mut n) = (0.0, 0usize);
    for k in 0..folds {
        let train: Vec<usize> = (0..obj.len()).filter(|i| i % folds != k).collect();
        let test: Vec<usize> = (0..obj.len()).filter(|i| i % folds == k).collect();
        let pts: Vec<(f64, f64)> = train.iter().map(|&i| obj[i]).collect();
        let fx = Poly2::fit(
            &pts,
            &train.iter().map(|&i| xs[i]).collect::<Vec<_>>(),
            order,
        )
        .ok()?;
        let fy = Poly2::fit(
            &pts,
            &train.iter().map(|&i| ys[i]).collect::<Vec<_>>(),
            order,
        )
        .ok()?;
        for &i in &test {
            se += (fx.eval(obj[i].0, obj[i].1) - xs[i]).powi(2)
                + (fy.eval(obj[i].0, obj[i].1) - ys[i]).powi(2);
            n += 1;
        }
    }
    (n > 0).then(|| (se / n as f64).sqrt())
}

/// Calibrates from a raw dot-grid frame with `per_side`² dots per tile. `order` fixes the
/// polynomial order; `None` picks the order (2…6) with the smallest held-out error.
pub fn calibrate(
    layout: &ArrayLayout,
    raw: &Image,
    per_side: usize,
    order: Option<usize>,
) -> Result<Calibration> {
    layout.validate()?;
    let dots = detect_dots(layout, raw)?;
    calibrate_from_dots(layout, &dots, per_side, order)
}

/// The fit of [`calibrate`] on dots already found by [`detect_dots`], so that several orders
/// can be tried without finding the dots again.
pub fn calibrate_from_dots(
    layout: &ArrayLayout,
    dots: &[Dot],
    per_side: usize,
    order: Option<usize>,
) -> Result<Calibration> {
    layout.validate()?;
    let (_, centres) = super::render::dot_grid_target(layout, per_side)?;
    let mut lenses = Vec::new();
    for (i, tile) in centres.iter().enumerate() {
        let expected: Vec<(f64, f64)> = tile
            .iter()
            .map(|&(x, y)| {
                nominal_sensor_position(layout, x, y)
                    .map(|(_, sx, sy)| (sx, sy))
                    .unwrap_or((f64::NAN, f64::NAN))
            })
            .collect();
        // Gate: a third of the closest spacing between expected dots.
        let mut spacing = f64::INFINITY;
        for (a, p) in expected.iter().enumerate() {
            for q in &expected[a + 1..] {
                spacing = spacing.min(((p.0 - q.0).powi(2) + (p.1 - q.1).powi(2)).sqrt());
            }
        }
        let gate = spacing / 3.0;
        let found: Vec<&Dot> = dots.iter().filter(|d| d.lens == i).collect();
        let mut used = vec![false; found.len()];
        let (mut obj, mut xs, mut ys) = (Vec::new(), Vec::new(), Vec::new());
        for (k, e) in expected.iter().enumerate() {
            let best = found
                .iter()
                .enumerate()
                .filter(|(j, _)| !used[*j])
                .map(|(j, d)| (j, ((d.x - e.0).powi(2) + (d.y - e.1).powi(2)).sqrt()))
                .min_by(|a, b| a.1.total_cmp(&b.1));
            if let Some((j, dist)) = best
                && dist <= gate
            {
                used[j] = true;
                obj.push(tile[k]);
                xs.push(found[j].x);
                ys.push(found[j].y);
            }
        }
        if obj.len() * 10 < tile.len() * 9 {
            return Err(Error::invalid(
                "grid image",
                format!(
                    "lens {}: found {} dots and matched {} of the {} expected; is this a grid frame of this layout?",
                    i + 1,
                    found.len(),
                    obj.len(),
                    tile.len()
                ),
            ));
        }
        let held_out: Vec<(usize, f64)> = match order {
            Some(o) => vec![(o, held_out_rms(&obj, &xs, &ys, o).unwrap_or(f64::NAN))],
            None => (2..=6)
                .filter(|&o| terms(o) * 5 / 4 < obj.len())
                .filter_map(|o| held_out_rms(&obj, &xs, &ys, o).map(|r| (o, r)))
                .collect(),
        };
        let chosen = match order {
            Some(o) => o,
            None => held_out
                .iter()
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .map(|p| p.0)
                .ok_or_else(|| {
                    Error::invalid(
                        "calibration",
                        format!("lens {}: too few dots for any polynomial order", i + 1),
                    )
                })?,
        };
        let fx = Poly2::fit(&obj, &xs, chosen)?;
        let fy = Poly2::fit(&obj, &ys, chosen)?;
        let errs: Vec<f64> = obj
            .iter()
            .zip(xs.iter().zip(&ys))
            .map(|(p, (x, y))| {
                ((fx.eval(p.0, p.1) - x).powi(2) + (fy.eval(p.0, p.1) - y).powi(2)).sqrt()
            })
            .collect();
        let rms_px = (errs.iter().map(|e| e * e).sum::<f64>() / errs.len() as f64).sqrt();
        let max_px = errs.iter().cloned().fold(0.0, f64::max);
        lenses.push(LensCalibration {
            fx,
            fy,
            dots: obj.len(),
            rms_px,
            max_px,
            held_out,
        });
    }
    Ok(Calibration {
        layout: layout.clone(),
        dots_per_side: per_side,
        lenses,
    })
}
