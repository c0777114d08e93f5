//! A PSF measured from captures of a point source (a pinhole or an LED far away), the measured
//! counterpart of Note S2's computed PSF as Note S4's blur uses it: the captures linearised
//! (Eq. S4 undone) and averaged, the dark frames and the remaining background (the border's
//! median) taken off, the noise floor (k standard deviations of the border, robust where the
//! border allows) clipped,
//! the centre found as the energy's centroid in a window around it, the image resampled
//! (Lanczos-3) so that the centre is the middle pixel of the smallest odd square holding the
//! asked share of the energy, and every channel normalised to sum 1.

use super::line_fit::median;
use super::support::{centroid, lanczos3, main_support, radius_holding};
use crate::error::{Error, Result};
use crate::optics::Psf;
use crate::types::Image;

/// Settings of the estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointOptions {
    /// Eq. S4's exponent the captures were encoded with (1 for linear captures).
    pub gamma: f64,
    /// Share of the energy (above the floor) the crop keeps.
    pub energy: f64,
    /// The noise floor, in robust standard deviations of the border's background.
    pub floor_k: f64,
}

impl Default for PointOptions {
    fn default() -> Self {
        Self {
            gamma: 1.7,
            energy: 0.99,
            floor_k: 3.0,
        }
    }
}

/// The estimate and where it came from.
#[derive(Clone, Debug, PartialEq)]
pub struct PointEstimate {
    pub psf: Psf,
    /// The centre in the captures (x, y), px.
    pub centre: (f64, f64),
    /// Per channel: the background taken off and the noise's robust standard deviation, in
    /// linear units of full scale.
    pub background: Vec<f64>,
    pub noise: Vec<f64>,
    /// Radius (px) around the centre holding 80 % of the kept energy, all channels together.
    pub ee80_radius: f64,
    /// Samples saturated in every exposure (their energy is underestimated: a shorter
    /// exposure would measure them).
    pub saturated: usize,
}

/// The PSF of the point source in `exposures` (each a set of captures `[C, H, W]` in [0, 1]
/// as read from the files, all of one shape, at one exposure; several exposures make one
/// high-dynamic-range image), `dark` frames of the same shape (may be empty).
///
/// With several exposures, their ratios are measured on the pixels that two neighbouring
/// exposures both see well (unsaturated in the brighter, well above the noise in the dimmer),
/// and each pixel is taken from the brightest exposure that does not saturate it: a long
/// exposure that saturates the core lifts the faint wings out of the noise.
pub fn estimate(
    exposures: &[Vec<Image>],
    dark: &[Image],
    opts: PointOptions,
) -> Result<PointEstimate> {
    let first = exposures
        .iter()
        .flatten()
        .next()
        .ok_or_else(|| Error::invalid("point source", "no capture"))?;
    let (c, h, w) = first.shape();
    if let Some(bad) = exposures
        .iter()
        .flatten()
        .chain(dark)
        .find(|im| im.shape() != (c, h, w))
    {
        return Err(Error::invalid(
            "point source",
            format!(
                "captures of {c}×{h}×{w} and {:?} differ in size: one camera setting",
                bad.shape()
            ),
        ));
    }
    if exposures.iter().any(Vec::is_empty) {
        return Err(Error::invalid("point source", "an exposure has no capture"));
    }
    if h < 16 || w < 16 {
        return Err(Error::invalid(
            "point source",
            format!("{w}×{h} is too small to hold a PSF and a border of background"),
        ));
    }
    let valid = opts.gamma.is_finite()
        && opts.gamma > 0.0
        && opts.energy > 0.0
        && opts.energy <= 1.0
        && opts.floor_k.is_finite()
        && opts.floor_k >= 0.0;
    if !valid {
        return Err(Error::invalid(
            "point source",
            format!(
                "gamma must be > 0, energy in (0, 1] and the floor >= 0, got {}, {}, {}",
                opts.gamma, opts.energy, opts.floor_k
            ),
        ));
    }
    let inv = 1.0 / opts.gamma;
    let n = c * h * w;
    let mean = |frames: &[Image]| -> Vec<f64> {
        let mut acc = vec![0.0f64; n];
        for f in frames {
            for (a, &v) in acc.iter_mut().zip(f.data()) {
                *a += (v as f64).clamp(0.0, 1.0).powf(inv);
            }
        }
        let k = frames.len().max(1) as f64;
        acc.iter_mut().for_each(|a| *a /= k);
        acc
    };
    let dark_mean = (!dark.is_empty()).then(|| mean(dark));
    // Each exposure: its mean, its saturated samples, the background and noise per channel.
    let ring = (h.min(w) / 20).max(2);
    let mut levels: Vec<Exposure> = exposures
        .iter()
        .map(|frames| {
            let mut m = mean(frames);
            if let Some(d) = &dark_mean {
                m.iter_mut().zip(d).for_each(|(v, d)| *v -= d);
            }
            let saturated = (0..n)
                .map(|i| frames.iter().any(|f| f.data()[i] >= SATURATED))
                .collect();
            let (background, noise) = background_and_noise(&mut m, c, h, w, ring);
            Exposure {
                signal: m,
                saturated,
                noise,
                background,
                scale: 1.0,
            }
        })
        .collect();
    // Dimmest first; each exposure's scale to the dimmest's units from its neighbour.
    levels.sort_by(|a, b| total_unsaturated(a).total_cmp(&total_unsaturated(b)));
    for k in 1..levels.len() {
        let (lo, hi) = levels.split_at_mut(k);
        let prev = &lo[k - 1];
        let cur = &mut hi[0];
        let (mut sp, mut sc) = (0.0, 0.0);
        for i in 0..n {
            let ch = i / (h * w);
            if !cur.saturated[i] && !prev.saturated[i] && prev.signal[i] > 10.0 * prev.noise[ch] {
                sp += prev.signal[i];
                sc += cur.signal[i];
            }
        }
        if !(sp > 0.0 && sc > 0.0) {
            return Err(Error::invalid(
                "point source",
                "two exposures share no pixel that both see well (unsaturated in the longer, \
                 above the noise in the shorter): space the exposures closer",
            ));
        }
        cur.scale = prev.scale * sc / sp;
    }
    // Each sample from the brightest exposure that does not saturate it, with its floor.
    let mut signal = vec![0.0f64; n];
    // A sample saturated in every exposure keeps the dimmest's value: an underestimate,
    // counted in the estimate.
    let mut saturated = 0;
    for (i, out) in signal.iter_mut().enumerate() {
        let ch = i / (h * w);
        let l = match levels.iter().rev().find(|l| !l.saturated[i]) {
            Some(l) => l,
            None => {
                saturated += 1;
                &levels[0]
            }
        };
        let v = l.signal[i] / l.scale;
        *out = if v > opts.floor_k * l.noise[ch] / l.scale {
            v
        } else {
            0.0
        };
    }
    // The dimmest exposure's background and noise, in the PSF's units.
    let (background, noise) = (levels[0].background.clone(), levels[0].noise.clone());
    // A point source stands far out of the noise: its brightest sample at least
    // `MIN_PEAK_SNR` times the dimmest exposure's noise.
    let peak_snr = (0..n)
        .map(|i| signal[i] / noise[i / (h * w)].max(1e-12))
        .fold(0.0f64, f64::max);
    if peak_snr < MIN_PEAK_SNR {
        return Err(Error::invalid(
            "point source",
            format!(
                "nothing stands out of the noise floor (the brightest sample is {peak_snr:.1} \
                 standard deviations of the noise): the point source is too faint, or missing"
            ),
        ));
    }
    // All channels together locate the centre (a lens's lateral colour stays in the PSF).
    let total: Vec<f64> = (0..h * w)
        .map(|i| (0..c).map(|ch| signal[ch * h * w + i]).sum())
        .collect();
    // What is left above the floor far from the source is noise (a spike, the clamped
    // noise's bias): only the connected parts of the support (gaps of a pixel bridged) that
    // hold at least 1 % of the largest part's energy stay.
    let keep = main_support(&total, w, h);
    for (i, k) in keep.iter().enumerate() {
        if !k {
            for ch in 0..c {
                signal[ch * h * w + i] = 0.0;
            }
        }
    }
    let total: Vec<f64> = total
        .iter()
        .zip(&keep)
        .map(|(&v, &k)| if k { v } else { 0.0 })
        .collect();
    if total.iter().all(|&v| v <= 0.0) {
        return Err(Error::invalid(
            "point source",
            "nothing above the noise floor: the point source is too faint, or missing",
        ));
    }
    // The centroid, then again within the square that holds the energy around it (stray
    // pixels above the floor far away no longer pull it).
    let mut centre = centroid(&total, w, None);
    for _ in 0..3 {
        let r = radius_holding(&total, w, centre, opts.energy).max(2.0);
        centre = centroid(&total, w, Some((centre, r)));
    }
    let r = radius_holding(&total, w, centre, opts.energy).ceil() as usize;
    let max_r = (h.min(w) - 1) / 2;
    let r = r.clamp(1, max_r);
    let side = 2 * r + 1;
    let mut out = Image::zeros(c, side, side);
    for ch in 0..c {
        let plane = &signal[ch * h * w..(ch + 1) * h * w];
        let dst = out.plane_mut(ch);
        for yy in 0..side {
            for xx in 0..side {
                let (sx, sy) = (
                    centre.0 + xx as f64 - r as f64,
                    centre.1 + yy as f64 - r as f64,
                );
                dst[yy * side + xx] = lanczos3(plane, w, h, sx, sy).max(0.0) as f32;
            }
        }
    }
    let psf = Psf::from_image(out, "measured PSF")?;
    let ee80_radius = encircled_radius(&psf, 0.8);
    Ok(PointEstimate {
        psf,
        centre,
        background,
        noise,
        ee80_radius,
        saturated,
    })
}

/// The radius (px) around a PSF's centre pixel holding `share` of its energy, all channels
/// together (linear between the pixels' distances).
pub fn encircled_radius(psf: &Psf, share: f64) -> f64 {
    let (h, w) = psf.size();
    let c = psf.channels();
    let mut px: Vec<(f64, f64)> = (0..h * w)
        .map(|i| {
            let (y, x) = (
                (i / w) as f64 - (h / 2) as f64,
                (i % w) as f64 - (w / 2) as f64,
            );
            let e: f64 = (0..c).map(|ch| psf.channel(ch)[i] as f64).sum();
            (x.hypot(y), e)
        })
        .collect();
    px.sort_by(|a, b| a.0.total_cmp(&b.0));
    let total: f64 = px.iter().map(|p| p.1).sum();
    let mut acc = 0.0;
    let mut last_r = 0.0;
    for (r, e) in px {
        if acc + e >= share * total {
            let f = if e > 0.0 {
                (share * total - acc) / e
            } else {
                1.0
            };
            return last_r + (r - last_r) * f;
        }
        acc += e;
        last_r = r;
    }
    last_r
}

/// The least peak signal-to-noise ratio of a point source's captures.
const MIN_PEAK_SNR: f64 = 20.0;

/// A sample at or above this (of full scale) is saturated: the top code of 8 bits.
const SATURATED: f32 = 254.5 / 255.0;

/// One exposure's averaged captures.
struct Exposure {
    /// Linear signal, background taken off, `[C, H, W]`.
    signal: Vec<f64>,
    /// Samples saturated in any of its captures.
    saturated: Vec<bool>,
    background: Vec<f64>,
    noise: Vec<f64>,
    /// Its signal over the dimmest exposure's.
    scale: f64,
}

fn total_unsaturated(e: &Exposure) -> f64 {
    // The saturated samples count at full scale: a longer exposure sums higher either way.
    e.signal
        .iter()
        .zip(&e.saturated)
        .map(|(&v, &s)| if s { 1.0 } else { v.max(0.0) })
        .sum()
}

/// Per channel of `signal` (`[C, H, W]`): the border ring's median (taken off in place) and
/// the noise's standard deviation there: robust (1.4826·MAD), or, where most of the border
/// is one code (dark backgrounds under a gamma above 1), the root mean square about the
/// median.
fn background_and_noise(
    signal: &mut [f64],
    c: usize,
    h: usize,
    w: usize,
    ring: usize,
) -> (Vec<f64>, Vec<f64>) {
    let (mut background, mut noise) = (Vec::with_capacity(c), Vec::with_capacity(c));
    for plane in signal.chunks_mut(h * w) {
        let border: Vec<f64> = (0..h * w)
            .filter(|i| {
                let (y, x) = (i / w, i % w);
                y < ring || x < ring || y >= h - ring || x >= w - ring
            })
            .map(|i| plane[i])
            .collect();
        let bg = median(&border);
        let mad = 1.4826 * median(&border.iter().map(|v| (v - bg).abs()).collect::<Vec<_>>());
        let sigma = if mad > 0.0 {
            mad
        } else {
            (border.iter().map(|v| (v - bg).powi(2)).sum::<f64>() / border.len() as f64).sqrt()
        };
        plane.iter_mut().for_each(|v| *v -= bg);
        background.push(bg);
        noise.push(sigma);
    }
    (background, noise)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::imaging::pipeline::Camera;
    use crate::imaging::similarity::compare;
    use crate::imaging::{CameraConfig, psf_source};

    /// `k` captures of a point at (x, y) (bilinear between pixels) through the default camera.
    fn captures(x: f64, y: f64, k: usize, gain: f32) -> (Vec<Image>, Psf) {
        let (psf, _) = psf_source::load("default").unwrap();
        let peak = psf.image().data().iter().fold(0.0f32, |m, &v| m.max(v));
        let cam = Camera::new(&CameraConfig::default(), psf.clone()).unwrap();
        let (h, w) = (200, 220);
        let mut scene = Image::zeros(3, h, w);
        // Bright enough that the PSF's peak reaches 90 % of full scale.
        let v = gain * 0.9 / (0.8 * peak);
        let (x0, y0) = (x.floor() as usize, y.floor() as usize);
        let (fx, fy) = ((x - x0 as f64) as f32, (y - y0 as f64) as f32);
        for c in 0..3 {
            for (dy, wy) in [(0, 1.0 - fy), (1, fy)] {
                for (dx, wx) in [(0, 1.0 - fx), (1, fx)] {
                    let old = scene.get(c, y0 + dy, x0 + dx);
                    scene.set(c, y0 + dy, x0 + dx, old + v * wx * wy);
                }
            }
        }
        let caps = (0..k)
            .map(|s| cam.apply(&scene, s as u64).unwrap())
            .collect();
        (caps, psf)
    }

    /// The truth cropped to the estimate's size (both odd and centred), as images at their
    /// own peak, and their SSIM.
    fn ssim(est: &Psf, truth: &Psf) -> f64 {
        let (s, _) = est.size();
        let (t, _) = truth.size();
        let crop = |p: &Psf, n: usize| -> Image {
            let (m, _) = p.size();
            let mut im = Image::zeros(p.channels(), n, n);
            for c in 0..p.channels() {
                let src = p.channel(c);
                for y in 0..n {
                    for x in 0..n {
                        let (sy, sx) = (
                            y as i64 + (m / 2) as i64 - (n / 2) as i64,
                            x as i64 + (m / 2) as i64 - (n / 2) as i64,
                        );
                        if sy >= 0 && sx >= 0 && (sy as usize) < m && (sx as usize) < m {
                            im.set(c, y, x, src[sy as usize * m + sx as usize]);
                        }
                    }
                }
            }
            let top = im.data().iter().fold(0.0f32, |a, &v| a.max(v));
            im.data_mut().iter_mut().for_each(|v| *v /= top);
            im
        };
        let n = s.min(t);
        compare(&crop(est, n), &crop(truth, n)).unwrap().ssim
    }

    #[test]
    fn recovers_the_shipped_psf_through_the_camera() {
        for (x, y) in [(110.0, 100.0), (109.3, 100.6)] {
            // One exposure with the peak at 90 % of full scale, one 30 times longer.
            let (short, truth) = captures(x, y, 16, 1.0);
            let (long, _) = captures(x, y, 16, 30.0);
            let est = estimate(&[short, long], &[], PointOptions::default()).unwrap();
            let s = ssim(&est.psf, &truth);
            let (re, rt) = (est.ee80_radius, encircled_radius(&truth, 0.8));
            eprintln!(
                "point at ({x}, {y}): centre {:?}, {:?} px, SSIM {s:.4}, EE80 {re:.2} px against {rt:.2}",
                est.centre,
                est.psf.size()
            );
            assert!(
                (est.centre.0 - x).abs() < 0.2 && (est.centre.1 - y).abs() < 0.2,
                "{:?}",
                est.centre
            );
            assert!(s >= 0.95, "SSIM {s}");
            assert!((re / rt - 1.0).abs() < 0.05, "EE80 {re} against {rt}");
        }
    }

    #[test]
    fn faint_or_mismatched_captures_are_refused() {
        let blank = vec![Image::filled(3, 40, 40, 0.1); 2];
        let e = estimate(std::slice::from_ref(&blank), &[], PointOptions::default()).unwrap_err();
        assert!(e.to_string().contains("noise floor"), "{e}");
        let e = estimate(
            &[blank],
            &[Image::filled(3, 30, 40, 0.1)],
            PointOptions::default(),
        )
        .unwrap_err();
        assert!(e.to_string().contains("differ in size"), "{e}");
        assert!(estimate(&[], &[], PointOptions::default()).is_err());
    }
}
