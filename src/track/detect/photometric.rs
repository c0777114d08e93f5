//! The photometric test of a detection (the brightness constancy behind every flow
//! method, Note S9): frame 2 warped back with the region's flow should match frame 1 clearly
//! better than frame 2 warped with the background's motion (zero for a still camera). A blob
//! of spurious flow on a still background explains nothing: warping with it does not lower
//! the residual, and the ratio of the two residuals stays near or above 1.

use std::sync::Arc;

use super::background::GlobalMotion;
use super::still_background::ColourFrame;
use crate::types::{Flow, Image};

/// One frame as a grey plane, lightly smoothed (3×3 box) against sensor noise, with its
/// 8-bit colour samples for the still background (`track::detect::still_background`); cheap to clone.
#[derive(Clone, Debug)]
pub struct GreyFrame {
    pub width: usize,
    pub height: usize,
    data: Arc<[f32]>,
    colour: ColourFrame,
}

impl GreyFrame {
    pub fn new(img: &Image) -> Self {
        let (h, w) = (img.height(), img.width());
        Self {
            width: w,
            height: h,
            data: smooth(&grey(img), w, h).into(),
            colour: ColourFrame::new(img),
        }
    }
}

/// What the frames say of a global motion (`GreyPair::judge`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MotionJudgement {
    /// The warp lowers the residual (`GreyPair::supports`).
    pub supported: bool,
    /// It lowers it by more than its interpolation of the noise does (`GreyPair::explains`).
    pub explained: bool,
}

/// Two consecutive frames.
#[derive(Clone, Debug)]
pub struct GreyPair {
    pub width: usize,
    pub height: usize,
    a: Arc<[f32]>,
    b: Arc<[f32]>,
    first: ColourFrame,
    second: ColourFrame,
}

impl GreyPair {
    /// `None` when the frames differ in size or have no pixels.
    pub fn new(first: &Image, second: &Image) -> Option<Self> {
        Self::of(&GreyFrame::new(first), &GreyFrame::new(second))
    }

    /// `None` when the frames differ in size or have no pixels.
    pub fn of(first: &GreyFrame, second: &GreyFrame) -> Option<Self> {
        let (h, w) = (first.height, first.width);
        if (second.height, second.width) != (h, w) || h == 0 || w == 0 {
            return None;
        }
        Some(Self {
            width: w,
            height: h,
            a: first.data.clone(),
            b: second.data.clone(),
            first: first.colour.clone(),
            second: second.colour.clone(),
        })
    }

    /// Frame 1's colour samples.
    pub fn first_colour(&self) -> &ColourFrame {
        &self.first
    }

    /// Frame 2's colour samples.
    pub fn second_colour(&self) -> &ColourFrame {
        &self.second
    }

    /// Mean |frame 1 − frame 2 warped by `flow`| and mean |frame 1 − frame 2 warped by
    /// `null`| over `pixels` (flat indices), counting only pixels whose both samples land
    /// inside the frame and whose flow is known; `None` when no pixel counts.
    pub fn residuals(
        &self,
        pixels: &[usize],
        flow: &Flow,
        null: &GlobalMotion,
    ) -> Option<(f64, f64)> {
        let (w, h) = (self.width, self.height);
        if (flow.width(), flow.height()) != (w, h) {
            return None;
        }
        let (u, v) = (flow.u(), flow.v());
        let (mut sf, mut sn, mut n) = (0.0f64, 0.0f64, 0usize);
        for &p in pixels {
            if p >= w * h {
                continue;
            }
            let (x, y) = ((p % w) as f64, (p / w) as f64);
            let (fu, fv) = (u[p] as f64, v[p] as f64);
            let (nu, nv) = null.at(x, y);
            if let (Some(bf), Some(bn)) = (self.sample(x + fu, y + fv), self.sample(x + nu, y + nv))
            {
                let a = self.a[p] as f64;
                sf += (a - bf).abs();
                sn += (a - bn).abs();
                n += 1;
            }
        }
        (n > 0).then(|| (sf / n as f64, sn / n as f64))
    }

    /// Mean |frame 1 − frame 2 shifted by the constant `motion`| over `pixels`, counting only
    /// pixels whose sample lands inside the frame; `None` when none does.
    pub fn residual_of(&self, pixels: &[usize], motion: (f64, f64)) -> Option<f64> {
        let w = self.width;
        let (mut s, mut n) = (0.0f64, 0usize);
        for &p in pixels {
            if p >= w * self.height {
                continue;
            }
            let (x, y) = ((p % w) as f64, (p / w) as f64);
            if let Some(b) = self.sample(x + motion.0, y + motion.1) {
                s += (self.a[p] as f64 - b).abs();
                n += 1;
            }
        }
        (n > 0).then(|| s / n as f64)
    }

    /// Whether the frames support the global `motion` over no motion at all: the mean |frame 1
    /// − frame 2 warped| over a regular grid of about `samples` pixels (each counted only where
    /// both warps land inside the frame) is lower with it. An estimated flow can carry a global
    /// bias of a pixel on a still, dark scene; subtracted as the background's motion, it would
    /// make every textured patch of the still scene "move", and with that background the
    /// photometric test would pass them. Movers add the same to both means. `None` when no
    /// grid pixel counts.
    pub fn supports(&self, motion: &GlobalMotion, samples: usize) -> Option<bool> {
        self.judge(motion, samples).map(|j| j.supported)
    }

    /// Whether the frames support the global `motion` by more than the warp's interpolation
    /// explains: as `supports`, with each pixel's residual without motion scaled by
    /// `interpolation_gain`. A warp by a fraction of a pixel averages frame 2's noise over its
    /// bilinear neighbours, which alone lowers the residual (by up to 8 % on a flat, noisy
    /// frame), so a still, flat or finely striped background "supports" any motion with a
    /// fractional part that an estimated flow gives it. Whether the camera moves is asked
    /// this way (`FrameDetection::place`); the photometric test's background stays the
    /// one `supports` accepts, whose warp interpolates both of its residuals alike.
    pub fn explains(&self, motion: &GlobalMotion, samples: usize) -> Option<bool> {
        self.judge(motion, samples).map(|j| j.explained)
    }

    /// `supports` and `explains` at once, over one pass of the grid; `None` when no grid
    /// pixel counts.
    pub fn judge(&self, motion: &GlobalMotion, samples: usize) -> Option<MotionJudgement> {
        let (w, h) = (self.width, self.height);
        let stride = (((h * w) as f64 / samples.max(16) as f64).sqrt().floor() as usize).max(1);
        let (mut with, mut without, mut fair, mut n) = (0.0f64, 0.0f64, 0.0f64, 0usize);
        for y in (stride / 2..h).step_by(stride) {
            for x in (stride / 2..w).step_by(stride) {
                let (xf, yf) = (x as f64, y as f64);
                let (mu, mv) = motion.at(xf, yf);
                if let (Some(bm), Some(bz)) = (self.sample(xf + mu, yf + mv), self.sample(xf, yf)) {
                    let a = self.a[y * w + x] as f64;
                    let still = (a - bz).abs();
                    with += (a - bm).abs();
                    without += still;
                    fair += interpolation_gain(mu, mv) * still;
                    n += 1;
                }
            }
        }
        (n > 0).then_some(MotionJudgement {
            supported: with < without,
            explained: with < fair,
        })
    }

    /// |frame 1 − frame 2 at the pixel moved by `shift`| at pixel `p` (a flat index); `None`
    /// outside the frame.
    pub fn residual_at(&self, p: usize, shift: (f64, f64)) -> Option<f64> {
        let w = self.width;
        if p >= w * self.height {
            return None;
        }
        let (x, y) = ((p % w) as f64, (p / w) as f64);
        self.sample(x + shift.0, y + shift.1)
            .map(|b| (self.a[p] as f64 - b).abs())
    }

    /// |frame 1 − frame 2 warped by `null`| at every pixel (`[H, W]`, grey levels in [0, 1]):
    /// the temporal difference with the background's motion compensated; NaN where the
    /// warped sample falls outside the frame.
    pub fn difference(&self, null: &GlobalMotion) -> Vec<f32> {
        let (w, h) = (self.width, self.height);
        let mut out = vec![f32::NAN; w * h];
        for y in 0..h {
            for x in 0..w {
                let (nu, nv) = null.at(x as f64, y as f64);
                if let Some(b) = self.sample(x as f64 + nu, y as f64 + nv) {
                    let p = y * w + x;
                    out[p] = (self.a[p] as f64 - b).abs() as f32;
                }
            }
        }
        out
    }

    /// Frame 2 at (x, y), bilinear; `None` outside the frame or for a non-finite position.
    fn sample(&self, x: f64, y: f64) -> Option<f64> {
        let (w, h) = (self.width, self.height);
        if !(x.is_finite() && y.is_finite())
            || x < 0.0
            || y < 0.0
            || x > (w - 1) as f64
            || y > (h - 1) as f64
        {
            return None;
        }
        let (x0, y0) = (x.floor() as usize, y.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
        let (fx, fy) = (x - x0 as f64, y - y0 as f64);
        let at = |xx: usize, yy: usize| self.b[yy * w + xx] as f64;
        Some(
            (1.0 - fy) * ((1.0 - fx) * at(x0, y0) + fx * at(x1, y0))
                + fy * ((1.0 - fx) * at(x0, y1) + fx * at(x1, y1)),
        )
    }
}

/// The correlation of adjacent pixels' noise in a grey plane (`GreyFrame`: its 3×3 box shares
/// 6 of 9 pixels between neighbours), for sensor noise that is independent pixel by pixel.
const NEIGHBOUR_CORRELATION: f64 = 2.0 / 3.0;

/// How much a bilinear warp by (`u`, `v`) alone lowers |frame 1 − frame 2| on pure noise of
/// equal variance in both grey planes: the interpolated sample's variance is g(fu)·g(fv) of a
/// pixel's, g(f) = (1 − f)² + f² + 2ρ·f(1 − f) for the fractional part f and the neighbours'
/// correlation ρ, so the difference's standard deviation is √((1 + g(fu)·g(fv)) / 2) of the
/// unwarped one: 1 at whole pixels, 0.92 at half a pixel both ways. Noise correlated over
/// more pixels (a demosaiced or compressed frame) is lowered less.
pub fn interpolation_gain(u: f64, v: f64) -> f64 {
    let g = |t: f64| {
        let f = t - t.floor();
        if f.is_finite() {
            1.0 - 2.0 * (1.0 - NEIGHBOUR_CORRELATION) * f * (1.0 - f)
        } else {
            1.0
        }
    };
    ((1.0 + g(u) * g(v)) / 2.0).sqrt()
}

/// The mean of the channels, one plane `[H, W]`.
fn grey(img: &Image) -> Vec<f32> {
    let (c, n) = (img.channels().max(1), img.height() * img.width());
    let mut g = vec![0.0f32; n];
    for k in 0..img.channels() {
        for (o, v) in g.iter_mut().zip(img.plane(k)) {
            *o += v / c as f32;
        }
    }
    g
}

/// A 3×3 box filter with the border clamped.
fn smooth(p: &[f32], w: usize, h: usize) -> Vec<f32> {
    if w == 0 || h == 0 {
        return Vec::new();
    }
    let mut out = vec![0.0f32; p.len()];
    for y in 0..h {
        for x in 0..w {
            let mut s = 0.0;
            for dy in [-1i64, 0, 1] {
                for dx in [-1i64, 0, 1] {
                    let yy = (y as i64 + dy).clamp(0, h as i64 - 1) as usize;
                    let xx = (x as i64 + dx).clamp(0, w as i64 - 1) as usize;
                    s += p[yy * w + xx];
                }
            }
            out[y * w + x] = s / 9.0;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth texture shifted by `dx` px in a 10×10 square at (20, 20) of frame 2.
    fn frames(dx: f64) -> (Image, Image) {
        let tex = |x: f64, y: f64| 0.5 + 0.2 * (x * 0.7).sin() * (y * 0.45).cos();
        let obj = |x: f64, y: f64| 0.5 + 0.3 * (x * 0.9 + 1.0).cos() * (y * 0.6).sin();
        let (w, h) = (64, 48);
        let (mut a, mut b) = (Image::zeros(1, h, w), Image::zeros(1, h, w));
        for y in 0..h {
            for x in 0..w {
                let (xf, yf) = (x as f64, y as f64);
                let in_a = (20.0..30.0).contains(&xf) && (20.0..30.0).contains(&yf);
                let in_b = (20.0 + dx..30.0 + dx).contains(&xf) && (20.0..30.0).contains(&yf);
                a.set(0, y, x, if in_a { obj(xf, yf) } else { tex(xf, yf) } as f32);
                b.set(
                    0,
                    y,
                    x,
                    if in_b { obj(xf - dx, yf) } else { tex(xf, yf) } as f32,
                );
            }
        }
        (a, b)
    }

    #[test]
    fn the_true_flow_explains_the_change_and_spurious_flow_does_not() {
        let (a, b) = frames(3.0);
        let pair = GreyPair::new(&a, &b).unwrap();
        let w = 64;
        let mut flow = Flow::zeros(48, 64);
        let mover: Vec<usize> = (22..28)
            .flat_map(|y| (22..28).map(move |x| y * w + x))
            .collect();
        for &p in &mover {
            flow.set(p / w, p % w, 3.0, 0.0);
        }
        // Spurious flow on the still background.
        let blob: Vec<usize> = (5..15)
            .flat_map(|y| (40..50).map(move |x| y * w + x))
            .collect();
        for &p in &blob {
            flow.set(p / w, p % w, 1.5, -1.0);
        }
        let zero = GlobalMotion::zero();
        let (rf, rn) = pair.residuals(&mover, &flow, &zero).unwrap();
        assert!(rf < 0.3 * rn, "mover: {rf} vs {rn}");
        let (rf, rn) = pair.residuals(&blob, &flow, &zero).unwrap();
        assert!(rf > rn, "blob: {rf} vs {rn}");
        // Outside pixels, unknown flow and a size mismatch count nothing.
        let mut out = Flow::zeros(48, 64);
        out.set(0, 0, -5.0, 0.0);
        out.set(0, 1, f32::NAN, 0.0);
        assert!(pair.residuals(&[0, 1, 99_999], &out, &zero).is_none());
        assert!(pair.residuals(&mover, &Flow::zeros(4, 4), &zero).is_none());
        assert!(GreyPair::new(&a, &Image::zeros(1, 4, 4)).is_none());
    }

    /// A still scene with noise: a global motion of a pixel (an estimated flow's bias) is not
    /// supported and zero is; the same scene panned by that motion supports it.
    #[test]
    fn the_frames_decide_whether_a_global_motion_is_real() {
        use crate::rng::stream;
        use rand_distr::{Distribution, StandardNormal};
        let (w, h) = (96, 72);
        let tex = |x: f64, y: f64| 0.4 + 0.15 * (x * 0.21).sin() * (y * 0.17).cos() + 0.002 * x;
        let (du, dv) = (0.9, -0.6);
        let mut rng = stream(5, &[1]);
        let mut noisy = |v: f64| {
            let n: f64 = StandardNormal.sample(&mut rng);
            (v + 0.01 * n) as f32
        };
        let (mut a, mut still, mut panned) = (
            Image::zeros(1, h, w),
            Image::zeros(1, h, w),
            Image::zeros(1, h, w),
        );
        for y in 0..h {
            for x in 0..w {
                let (xf, yf) = (x as f64, y as f64);
                a.set(0, y, x, noisy(tex(xf, yf)));
                still.set(0, y, x, noisy(tex(xf, yf)));
                panned.set(0, y, x, noisy(tex(xf - du, yf - dv)));
            }
        }
        let mut bias = GlobalMotion::zero();
        bias.params[0] = du;
        bias.params[3] = dv;
        let still = GreyPair::new(&a, &still).unwrap();
        let panned = GreyPair::new(&a, &panned).unwrap();
        assert_eq!(still.supports(&bias, 4096), Some(false));
        assert_eq!(panned.supports(&bias, 4096), Some(true));
        assert_eq!(still.explains(&bias, 4096), Some(false));
        assert_eq!(panned.explains(&bias, 4096), Some(true));
        // A single pixel: no grid point has both warps inside.
        let one = GreyPair::new(&Image::zeros(1, 1, 1), &Image::zeros(1, 1, 1)).unwrap();
        assert_eq!(one.supports(&bias, 16), None);
    }

    /// The interpolation's gain is 1 at whole pixels and √(5/8) at half a pixel both ways, and
    /// it is what a warp alone does to pure noise.
    #[test]
    fn a_fractional_warp_lowers_the_residual_of_pure_noise_by_its_gain() {
        use crate::rng::stream;
        use rand_distr::{Distribution, StandardNormal};
        assert!((interpolation_gain(3.0, -2.0) - 1.0).abs() < 1e-12);
        // g(½) = 5/6 with the box's correlation of 2/3.
        let half = ((1.0 + 25.0 / 36.0) / 2.0f64).sqrt();
        assert!((interpolation_gain(0.5, -1.5) - half).abs() < 1e-12);
        assert!((interpolation_gain(0.5, 0.0) - (11.0f64 / 12.0).sqrt()).abs() < 1e-12);
        assert_eq!(interpolation_gain(f64::NAN, 0.0), 1.0);
        let (w, h) = (480, 360);
        let mut rng = stream(8, &[2]);
        let mut noise = || {
            let mut img = Image::zeros(1, h, w);
            for y in 0..h {
                for x in 0..w {
                    let n: f64 = StandardNormal.sample(&mut rng);
                    img.set(0, y, x, (0.5 + 0.01 * n) as f32);
                }
            }
            img
        };
        let pair = GreyPair::new(&noise(), &noise()).unwrap();
        let pixels: Vec<usize> = (0..w * h).collect();
        let still = pair.residual_of(&pixels, (0.0, 0.0)).unwrap();
        for m in [(0.5, 0.5), (2.25, -0.4), (-3.7, 0.0)] {
            let warped = pair.residual_of(&pixels, m).unwrap() / still;
            let gain = interpolation_gain(m.0, m.1);
            assert!(
                gain < 0.99 && (warped - gain).abs() < 0.015,
                "{m:?}: the warp's ratio {warped:.3}, the gain {gain:.3}"
            );
        }
    }

    /// A still, nearly flat background under noise (a wall, a dark sky through the camera):
    /// an estimated flow's spurious motion of (3.5, 0.5) px lowers the warped residual by
    /// interpolating the noise, not by explaining the frames: `supports` takes it, `explains`
    /// does not.
    #[test]
    fn a_fractional_motion_on_a_still_flat_background_is_not_explained() {
        use crate::rng::stream;
        use rand_distr::{Distribution, StandardNormal};
        let (w, h) = (160, 120);
        let faint = |x: f64| 0.45 + 0.002 * (x * std::f64::consts::TAU / 64.0).sin();
        let mut rng = stream(9, &[4]);
        let mut frame = || {
            let mut img = Image::zeros(1, h, w);
            for y in 0..h {
                for x in 0..w {
                    let n: f64 = StandardNormal.sample(&mut rng);
                    img.set(0, y, x, (faint(x as f64) + 0.01 * n) as f32);
                }
            }
            img
        };
        let still = GreyPair::new(&frame(), &frame()).unwrap();
        let (du, dv) = (3.5, 0.5);
        let all: Vec<usize> = (0..w * h).collect();
        // Compared as they are, the warp would win.
        let (warped, unwarped) = (
            still.residual_of(&all, (du, dv)).unwrap(),
            still.residual_of(&all, (0.0, 0.0)).unwrap(),
        );
        assert!(warped < unwarped, "{warped} {unwarped}");
        let mut bias = GlobalMotion::zero();
        bias.params[0] = du;
        bias.params[3] = dv;
        assert_eq!(still.supports(&bias, 4096), Some(true));
        assert_eq!(still.explains(&bias, 4096), Some(false));
    }
}
