//! Where a point source's energy lies in a capture and how to move it (`point_source`): the
//! significant connected support, the energy's centroid, the square holding a share of the
//! energy, and Lanczos-3 resampling.

/// The pixels of the support's significant parts: 8-connected components of the positive
/// pixels, a one-pixel gap bridged, with at least 1 % of the largest component's energy.
pub(super) fn main_support(v: &[f64], w: usize, h: usize) -> Vec<bool> {
    let mut label = vec![usize::MAX; v.len()];
    let mut energy = Vec::new();
    let mut stack = Vec::new();
    for start in 0..v.len() {
        if v[start] <= 0.0 || label[start] != usize::MAX {
            continue;
        }
        let id = energy.len();
        let mut e = 0.0;
        label[start] = id;
        stack.push(start);
        while let Some(i) = stack.pop() {
            e += v[i];
            let (y, x) = ((i / w) as i64, (i % w) as i64);
            for dy in -2i64..=2 {
                for dx in -2i64..=2 {
                    let (ny, nx) = (y + dy, x + dx);
                    if ny < 0 || nx < 0 || ny >= h as i64 || nx >= w as i64 {
                        continue;
                    }
                    let j = ny as usize * w + nx as usize;
                    if v[j] > 0.0 && label[j] == usize::MAX {
                        label[j] = id;
                        stack.push(j);
                    }
                }
            }
        }
        energy.push(e);
    }
    let top = energy.iter().fold(0.0f64, |m, &e| m.max(e));
    label
        .iter()
        .map(|&l| l != usize::MAX && energy[l] >= 0.01 * top)
        .collect()
}

/// The energy's centroid (x, y), over the whole image or a square window (centre, half-side).
pub(super) fn centroid(v: &[f64], w: usize, window: Option<((f64, f64), f64)>) -> (f64, f64) {
    let (mut s, mut sx, mut sy) = (0.0, 0.0, 0.0);
    for (i, &e) in v.iter().enumerate() {
        let (x, y) = ((i % w) as f64, (i / w) as f64);
        if let Some(((cx, cy), r)) = window
            && ((x - cx).abs() > r || (y - cy).abs() > r)
        {
            continue;
        }
        s += e;
        sx += e * x;
        sy += e * y;
    }
    if s > 0.0 {
        (sx / s, sy / s)
    } else {
        (0.0, 0.0)
    }
}

/// The half-side of the square around `centre` holding `share` of the energy.
pub(super) fn radius_holding(v: &[f64], w: usize, centre: (f64, f64), share: f64) -> f64 {
    let mut d: Vec<(f64, f64)> = v
        .iter()
        .enumerate()
        .filter(|(_, e)| **e > 0.0)
        .map(|(i, &e)| {
            let (x, y) = ((i % w) as f64, (i / w) as f64);
            ((x - centre.0).abs().max((y - centre.1).abs()), e)
        })
        .collect();
    d.sort_by(|a, b| a.0.total_cmp(&b.0));
    let total: f64 = d.iter().map(|p| p.1).sum();
    let mut acc = 0.0;
    for (r, e) in d {
        acc += e;
        if acc >= share * total {
            return r;
        }
    }
    0.0
}

/// Lanczos-3 interpolation of `plane` (`w × h`) at (x, y); outside the image is 0.
pub(super) fn lanczos3(plane: &[f64], w: usize, h: usize, x: f64, y: f64) -> f64 {
    let kernel = |t: f64| -> f64 {
        if t.abs() < 1e-12 {
            1.0
        } else if t.abs() >= 3.0 {
            0.0
        } else {
            let p = std::f64::consts::PI * t;
            3.0 * p.sin() * (p / 3.0).sin() / (p * p)
        }
    };
    let (x0, y0) = (x.floor() as i64, y.floor() as i64);
    let mut acc = 0.0;
    for j in y0 - 2..=y0 + 3 {
        if j < 0 || j >= h as i64 {
            continue;
        }
        let ky = kernel(y - j as f64);
        if ky == 0.0 {
            continue;
        }
        for i in x0 - 2..=x0 + 3 {
            if i < 0 || i >= w as i64 {
                continue;
            }
            acc += ky * kernel(x - i as f64) * plane[j as usize * w + i as usize];
        }
    }
    acc
}
