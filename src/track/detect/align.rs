//! The region's motion that the frames confirm (Note S13's region of interest, Eq. S18's
//! speed): the translation that best maps the region's colours in frame n onto frame n + 1,
//! the least mean |I₁(p) − I₂(p + d)| over the region's pixels (3×3 box-smoothed R, G and B),
//! searched on the integer grid around the region's mean flow and refined to a fraction of a
//! pixel by a parabola through the neighbouring costs. An estimated flow finds a small,
//! low-contrast mover but smooths its motion into the still background around it (MMS gives
//! 2 px/frame inside a disc that moves 6); block matching, the oldest motion estimator, has
//! no such prior, and over a whole region it is precise. Colour matters: a dark, flat disc on
//! a green background is nearly invisible in grey. The channels are weighted
//! (`ALIGN_WEIGHTS`): the metalens PSF is sharp in green and broad in red and blue, whose
//! pixels on a small mover carry a halo of its still surroundings that pulls the match towards
//! no motion.

use super::still_background::ColourFrame;

/// The aligned motion of one region.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aligned {
    /// The translation (px/frame) that best explains the region's change.
    pub motion: (f64, f64),
    /// Mean colour residual (levels in [0, 1], the channels' weighted mean) with `motion` ...
    pub residual: f64,
    /// ... and with the starting motion (the region's mean flow), both over the same pixels.
    pub start_residual: f64,
}

/// A 3×3 box-smoothed rectangle of a colour frame, `[C, y1 − y0 + 1, x1 − x0 + 1]`, values in
/// [0, 1]; the frame's border is clamped.
struct Patch {
    x0: i64,
    y0: i64,
    w: usize,
    h: usize,
    channels: usize,
    data: Vec<f32>,
}

impl Patch {
    fn of(frame: &ColourFrame, x0: i64, y0: i64, x1: i64, y1: i64) -> Self {
        let (fw, fh) = (frame.width as i64, frame.height as i64);
        let (x0, y0) = (x0.clamp(0, fw - 1), y0.clamp(0, fh - 1));
        let (x1, y1) = (x1.clamp(x0, fw - 1), y1.clamp(y0, fh - 1));
        let (w, h) = ((x1 - x0 + 1) as usize, (y1 - y0 + 1) as usize);
        let channels = frame.channels.max(1);
        let mut data = vec![0.0f32; channels * w * h];
        for c in 0..channels {
            let plane = frame.plane(c);
            for y in 0..h {
                for x in 0..w {
                    let (gx, gy) = (x0 + x as i64, y0 + y as i64);
                    let mut s = 0u32;
                    for dy in -1..=1i64 {
                        let yy = (gy + dy).clamp(0, fh - 1) as usize;
                        for dx in -1..=1i64 {
                            let xx = (gx + dx).clamp(0, fw - 1) as usize;
                            s += plane[yy * frame.width + xx] as u32;
                        }
                    }
                    data[(c * h + y) * w + x] = s as f32 / (9.0 * 255.0);
                }
            }
        }
        Self {
            x0,
            y0,
            w,
            h,
            channels,
            data,
        }
    }

    /// Channel `c` at frame pixel (x, y); `None` outside the patch.
    fn at(&self, c: usize, x: i64, y: i64) -> Option<f32> {
        let (px, py) = (x - self.x0, y - self.y0);
        (px >= 0 && py >= 0 && (px as usize) < self.w && (py as usize) < self.h)
            .then(|| self.data[(c * self.h + py as usize) * self.w + px as usize])
    }

    /// Channel `c` at the frame position (x, y), bilinear; `None` unless all four neighbours
    /// lie in the patch.
    fn sample(&self, c: usize, x: f64, y: f64) -> Option<f64> {
        if !(x.is_finite() && y.is_finite()) {
            return None;
        }
        let (xf, yf) = (x.floor(), y.floor());
        let (ix, iy) = (xf as i64, yf as i64);
        let (fx, fy) = (x - xf, y - yf);
        let a = self.at(c, ix, iy)? as f64;
        let b = self.at(c, ix + 1, iy)? as f64;
        let d = self.at(c, ix, iy + 1)? as f64;
        let e = self.at(c, ix + 1, iy + 1)? as f64;
        Some((1.0 - fy) * ((1.0 - fx) * a + fx * b) + fy * ((1.0 - fx) * d + fx * e))
    }
}

/// The default weights of the R, G and B residuals. The default camera's PSF
/// (`datasets/psf/metalens_default.npy`) leaves 35 % (red), 76 % (green) and 40 % (blue) of the
/// light on an 18-px disc's pixels from the disc itself, the rest from around it; with equal
/// weights the aligned motion of the single-disc clips falls 4–9 % short of the true motion.
pub const ALIGN_WEIGHTS: [f64; 3] = [0.25, 1.0, 0.25];

/// Channel weights the alignment takes: finite, non-negative, not all zero.
pub fn weights_valid(weights: &[f64; 3]) -> bool {
    weights.iter().all(|w| w.is_finite() && *w >= 0.0) && weights.iter().sum::<f64>() > 0.0
}

/// Of all shifts, a pixel set must keep this share of its pixels inside frame 2.
const MIN_INSIDE: f64 = 0.75;
/// The integer search uses at most this many of the region's pixels (evenly spread).
const SEARCH_PIXELS: usize = 1500;

/// The motion of the region `pixels` (flat indices into frame n, `[H, W]`) that best maps
/// frame `first` onto frame `second`, searched within `reach` px of `start` (the region's
/// mean flow) on each axis, where `reach` = ⌈1.5 |start|⌉ + 3 capped at `max_reach`: an
/// estimated flow on a small mover falls short by up to 3×. A colour frame's channels count
/// with `weights` (R, G, B; a grey frame's one channel with 1). `None` when the frames differ
/// in size, the region is empty, no shift keeps three quarters of it inside frame 2, or the
/// weights are not finite and non-negative with a positive sum.
pub fn align(
    first: &ColourFrame,
    second: &ColourFrame,
    pixels: &[usize],
    start: (f64, f64),
    max_reach: usize,
    weights: [f64; 3],
) -> Option<Aligned> {
    let (w, h) = (first.width, first.height);
    if (second.width, second.height) != (w, h)
        || first.channels != second.channels
        || pixels.is_empty()
        || !(start.0.is_finite() && start.1.is_finite())
        || !weights_valid(&weights)
    {
        return None;
    }
    let pixels: Vec<usize> = pixels.iter().copied().filter(|&p| p < w * h).collect();
    let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
    for &p in &pixels {
        let (x, y) = (p % w, p / w);
        (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
    }
    if pixels.is_empty() {
        return None;
    }
    let speed = start.0.hypot(start.1);
    let reach = ((1.5 * speed).ceil() as usize + 3).min(max_reach.max(1)) as i64;
    let (cx, cy) = (start.0.round() as i64, start.1.round() as i64);
    let a = Patch::of(first, x0 as i64, y0 as i64, x1 as i64, y1 as i64);
    let b = Patch::of(
        second,
        x0 as i64 + cx - reach - 2,
        y0 as i64 + cy - reach - 2,
        x1 as i64 + cx + reach + 2,
        y1 as i64 + cy + reach + 2,
    );
    let channels = a.channels;
    // Per channel: [C].
    let cw: Vec<f32> = if channels == 3 {
        weights.iter().map(|&w| w as f32).collect()
    } else {
        vec![1.0; channels]
    };
    let weight_sum: f64 = cw.iter().map(|&w| w as f64).sum();
    // Frame n's smoothed colours at the region's pixels: [N][C].
    let colours: Vec<(i64, i64, Vec<f32>)> = pixels
        .iter()
        .filter_map(|&p| {
            let (x, y) = ((p % w) as i64, (p / w) as i64);
            let v: Option<Vec<f32>> = (0..channels).map(|c| a.at(c, x, y)).collect();
            v.map(|v| (x, y, v))
        })
        .collect();
    let stride = colours.len().div_ceil(SEARCH_PIXELS).max(1);
    let search: Vec<&(i64, i64, Vec<f32>)> = colours.iter().step_by(stride).collect();
    let need = (MIN_INSIDE * search.len() as f64).ceil() as usize;
    let cost = |dx: i64, dy: i64| -> Option<f64> {
        let (mut s, mut n) = (0.0f64, 0usize);
        for (x, y, v) in &search {
            let mut e = 0.0f32;
            for (c, &va) in v.iter().enumerate() {
                e += cw[c] * (va - b.at(c, x + dx, y + dy)?).abs();
            }
            s += e as f64;
            n += 1;
        }
        (n >= need.max(1)).then(|| s / (n as f64 * weight_sum))
    };
    let side = (2 * reach + 1) as usize;
    let mut grid = vec![None; side * side];
    let mut best: Option<(f64, i64, i64)> = None;
    for j in 0..side {
        for i in 0..side {
            let (dx, dy) = (cx - reach + i as i64, cy - reach + j as i64);
            let c = cost(dx, dy);
            grid[j * side + i] = c;
            if let Some(c) = c
                && best.is_none_or(|b| c < b.0)
            {
                best = Some((c, dx, dy));
            }
        }
    }
    let (c0, bx, by) = best?;
    let at = |dx: i64, dy: i64| -> Option<f64> {
        let (i, j) = (dx - cx + reach, dy - cy + reach);
        if i < 0 || j < 0 || i >= side as i64 || j >= side as i64 {
            return None;
        }
        grid[j as usize * side + i as usize]
    };
    // A parabola through the minimum and its two neighbours on each axis.
    let vertex = |m: Option<f64>, p: Option<f64>| -> f64 {
        match (m, p) {
            (Some(m), Some(p)) => {
                let curv = m - 2.0 * c0 + p;
                if curv > 1e-12 {
                    (0.5 * (m - p) / curv).clamp(-0.5, 0.5)
                } else {
                    0.0
                }
            }
            _ => 0.0,
        }
    };
    let motion = (
        bx as f64 + vertex(at(bx - 1, by), at(bx + 1, by)),
        by as f64 + vertex(at(bx, by - 1), at(bx, by + 1)),
    );
    // Both residuals over every pixel that both shifts keep inside the patch.
    let (mut sm, mut ss, mut n) = (0.0f64, 0.0f64, 0usize);
    for (x, y, v) in &colours {
        let (xf, yf) = (*x as f64, *y as f64);
        let mut em = 0.0;
        let mut es = 0.0;
        let mut inside = true;
        for (c, &va) in v.iter().enumerate() {
            match (
                b.sample(c, xf + motion.0, yf + motion.1),
                b.sample(c, xf + start.0, yf + start.1),
            ) {
                (Some(m), Some(s)) => {
                    em += cw[c] as f64 * (va as f64 - m).abs();
                    es += cw[c] as f64 * (va as f64 - s).abs();
                }
                _ => inside = false,
            }
        }
        if inside {
            sm += em;
            ss += es;
            n += 1;
        }
    }
    if n == 0 {
        return None;
    }
    let k = n as f64 * weight_sum;
    Some(Aligned {
        motion,
        residual: sm / k,
        start_residual: ss / k,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::imaging::box_filter::box_mean;
    use crate::rng::stream;
    use crate::types::Image;
    use rand_distr::{Distribution, StandardNormal};

    /// A still textured background and a disc of radius 12 with its own texture at (60, 50)
    /// in frame 1, moved by `motion` in frame 2; noise of σ = `noise` on every pixel.
    fn frames(motion: (f64, f64), noise: f64, seed: u64) -> (ColourFrame, ColourFrame) {
        let (w, h) = (128, 100);
        let bg = |x: f64, y: f64, c: usize| {
            0.35 + 0.12 * (x * 0.23 + c as f64).sin() * (y * 0.19 - c as f64).cos()
        };
        let obj = |x: f64, y: f64, c: usize| {
            0.55 + 0.2 * (x * 0.5 + 2.0 * c as f64).cos() * (y * 0.41).sin()
        };
        let mut rng = stream(seed, &[9]);
        let mut draw = |centre: (f64, f64)| {
            let mut img = Image::zeros(3, h, w);
            for c in 0..3 {
                for y in 0..h {
                    for x in 0..w {
                        let (xf, yf) = (x as f64, y as f64);
                        let (ox, oy) = (xf - centre.0, yf - centre.1);
                        let v = if ox.hypot(oy) <= 12.0 {
                            obj(ox, oy, c)
                        } else {
                            bg(xf, yf, c)
                        };
                        let n: f64 = StandardNormal.sample(&mut rng);
                        img.set(c, y, x, (v + noise * n) as f32);
                    }
                }
            }
            ColourFrame::new(&img)
        };
        let a = draw((60.0, 50.0));
        let b = draw((60.0 + motion.0, 50.0 + motion.1));
        (a, b)
    }

    fn disc_pixels(w: usize, centre: (f64, f64), r: f64) -> Vec<usize> {
        let mut v = Vec::new();
        for y in 0..100usize {
            for x in 0..w {
                if (x as f64 - centre.0).hypot(y as f64 - centre.1) <= r {
                    v.push(y * w + x);
                }
            }
        }
        v
    }

    /// The flow says a third of the motion (as MMS does on a small mover): the frames give
    /// the whole of it, to a fraction of a pixel, with a lower residual than the flow's.
    #[test]
    fn a_flow_that_falls_short_is_corrected_by_the_frames() {
        for (k, motion) in [(6.0, -2.0), (-4.4, 3.3), (0.0, 7.0), (9.5, 0.5)]
            .into_iter()
            .enumerate()
        {
            let (a, b) = frames(motion, 0.02, k as u64);
            let pixels = disc_pixels(128, (60.0, 50.0), 11.0);
            let start = (motion.0 / 3.0, motion.1 / 3.0);
            let r = align(&a, &b, &pixels, start, 24, ALIGN_WEIGHTS).unwrap();
            let err = (r.motion.0 - motion.0).hypot(r.motion.1 - motion.1);
            assert!(err < 0.35, "{motion:?}: aligned {:?}", r.motion);
            assert!(
                r.residual < 0.6 * r.start_residual,
                "{motion:?}: {} vs {}",
                r.residual,
                r.start_residual
            );
        }
    }

    /// A patch of the still background under spurious flow: the frames say it does not move.
    #[test]
    fn a_still_patch_aligns_to_no_motion() {
        let (a, b) = frames((5.0, 0.0), 0.02, 3);
        let pixels = disc_pixels(128, (25.0, 25.0), 10.0);
        let r = align(&a, &b, &pixels, (1.5, -1.0), 24, ALIGN_WEIGHTS).unwrap();
        assert!(r.motion.0.hypot(r.motion.1) < 0.3, "{:?}", r.motion);
    }

    /// A disc as on the clips: set apart from a textured still background by its red and blue
    /// levels, with a faint texture of its own in green; seen through a chromatic PSF (red and
    /// blue keep 35 % of each pixel's light and spread the rest over a 25×25 box, green is
    /// sharp), no noise.
    fn chromatic_frames(motion: (f64, f64)) -> (ColourFrame, ColourFrame) {
        let (w, h) = (128, 100);
        let scene = |centre: (f64, f64), c: usize, x: f64, y: f64| {
            let (ox, oy) = (x - centre.0, y - centre.1);
            // Red and blue ramp across the frame (the large-scale light a broad PSF spreads).
            let ramp = match c {
                0 => 0.6 * x / w as f64 - 0.3,
                2 => 0.6 * y / h as f64 - 0.3,
                _ => 0.0,
            };
            let bg = 0.35 + ramp + 0.08 * (x * 0.23 + c as f64).sin() * (y * 0.19 - c as f64).cos();
            if ox.hypot(oy) > 12.0 {
                return bg;
            }
            match c {
                0 => 0.2,
                2 => 0.6,
                _ => 0.35 + 0.05 * (ox * 0.7).cos() * (oy * 0.6).sin(),
            }
        };
        let draw = |centre: (f64, f64)| {
            let mut img = Image::zeros(3, h, w);
            for c in 0..3 {
                let sharp: Vec<f32> = (0..w * h)
                    .map(|i| scene(centre, c, (i % w) as f64, (i / w) as f64) as f32)
                    .collect();
                let out = if c == 1 {
                    sharp
                } else {
                    let (blurred, _) = box_mean(&sharp, w, h, 12);
                    sharp
                        .iter()
                        .zip(&blurred)
                        .map(|(v, b)| 0.35 * v + 0.65 * b)
                        .collect()
                };
                for (i, v) in out.into_iter().enumerate() {
                    img.set(c, i / w, i % w, v);
                }
            }
            ColourFrame::new(&img)
        };
        (draw((60.0, 50.0)), draw((60.0 + motion.0, 50.0 + motion.1)))
    }

    /// Through a PSF that is broad in red and blue, equal weights pull the match towards no
    /// motion (the blurred channels carry the still background's halo); the default weights,
    /// green first, keep the motion.
    #[test]
    fn green_first_keeps_the_motion_a_chromatic_halo_shortens() {
        let pixels = disc_pixels(128, (60.0, 50.0), 11.0);
        for motion in [(6.0, -2.0), (-4.4, 3.3), (0.0, 7.0)] {
            let (a, b) = chromatic_frames(motion);
            let start = (motion.0 / 3.0, motion.1 / 3.0);
            let along = |weights| {
                let r = align(&a, &b, &pixels, start, 24, weights).expect("aligned");
                let s = motion.0.hypot(motion.1);
                (r.motion.0 * motion.0 + r.motion.1 * motion.1) / s - s
            };
            let (equal, green) = (along([1.0, 1.0, 1.0]), along(ALIGN_WEIGHTS));
            assert!(
                green.abs() < 0.5 * equal.abs(),
                "{motion:?}: equal {equal:+.3}, green {green:+.3}"
            );
        }
    }

    #[test]
    fn bad_input_gives_none() {
        let (a, b) = frames((2.0, 0.0), 0.0, 1);
        assert!(align(&a, &b, &[], (0.0, 0.0), 24, ALIGN_WEIGHTS).is_none());
        assert!(align(&a, &b, &[5], (f64::NAN, 0.0), 24, ALIGN_WEIGHTS).is_none());
        let small = ColourFrame::new(&Image::zeros(3, 4, 4));
        assert!(align(&a, &small, &[5], (0.0, 0.0), 24, ALIGN_WEIGHTS).is_none());
        // Pixels outside the frame are ignored; a region left empty gives none.
        assert!(align(&a, &b, &[10_000_000], (0.0, 0.0), 24, ALIGN_WEIGHTS).is_none());
        // Weights must be finite, non-negative and not all zero.
        for w in [[0.0; 3], [1.0, f64::NAN, 1.0], [1.0, -0.5, 1.0]] {
            assert!(
                align(&a, &b, &[5, 6, 7], (0.0, 0.0), 24, w).is_none(),
                "{w:?}"
            );
        }
    }
}
