//! Photon transfer (the EMVA 1288 method) for Note S4's Eq. S3, σ² = a·y + b in 8-bit DN:
//! from flat-field captures at several levels, each level's mean signal and temporal
//! variance per channel, and the line through them, with confidence intervals.
//!
//! The captures are first brought back to the sensor's linear signal (Eq. S4 undone:
//! y = 255·v^(1/γ)). The temporal variance of a level is the per-pixel variance across its
//! captures, averaged over the pixels: a fixed pattern (vignetting, dust, the PSF's structure)
//! cancels. What quantisation adds (Sheppard's step²/12, with the step the linear size of one
//! code at that pixel's value) is taken off. A level with samples at the bottom or top code
//! (clipped by the sensor) is left out: clipping shrinks the variance.

use crate::error::{Error, Result};
use crate::types::Image;

use super::line_fit::{LineFit, fit_line};

/// The largest share of a level's samples that may sit at the lowest or highest code.
pub const MAX_CLIPPED: f64 = 1e-4;

/// How the captures were encoded.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Encoding {
    /// Eq. S4's exponent (1 for a linear raw capture).
    pub gamma: f64,
    /// Bits per sample of the files (8 or 16).
    pub bits: u8,
}

/// One level's statistics in one channel (8-bit linear DN).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Level {
    /// The level's name (the captures' common prefix).
    pub name: String,
    pub channel: usize,
    pub captures: usize,
    /// Degrees of freedom of the variance: pixels × (captures − 1).
    pub dof: usize,
    /// Mean signal over pixels and captures, the dark level taken off where dark frames
    /// were given.
    pub mean: f64,
    /// Temporal variance, the quantisation's share taken off (DN²).
    pub variance: f64,
    /// The quantisation's share that was taken off (DN²).
    pub quantisation: f64,
    /// Share of samples at the lowest or highest code.
    pub clipped: f64,
    /// Why the fit leaves it out, if it does.
    pub excluded: Option<String>,
}

/// The fit of one channel, or of all channels pooled.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct NoiseFit {
    /// `None` for the pooled fit.
    pub channel: Option<usize>,
    pub line: LineFit,
}

/// Statistics of one level's captures, each `[C, H, W]` in [0, 1] as read from the files
/// (all the same shape, at least two).
pub fn level_stats(
    name: &str,
    captures: &[Image],
    enc: Encoding,
    dark: Option<&[f64]>,
) -> Result<Vec<Level>> {
    let first = captures
        .first()
        .ok_or_else(|| Error::invalid("captures", format!("level {name} has no capture")))?;
    if captures.len() < 2 {
        return Err(Error::invalid(
            "captures",
            format!(
                "level {name} has one capture; the temporal variance needs at least two of each level"
            ),
        ));
    }
    let (c, h, w) = first.shape();
    if let Some(bad) = captures.iter().find(|im| im.shape() != (c, h, w)) {
        return Err(Error::invalid(
            "captures",
            format!(
                "level {name}: captures of {}×{}×{} and {:?} differ in size",
                c,
                h,
                w,
                bad.shape()
            ),
        ));
    }
    if !(enc.gamma.is_finite() && enc.gamma > 0.0) || !(enc.bits == 8 || enc.bits == 16) {
        return Err(Error::invalid(
            "encoding",
            format!(
                "gamma must be > 0 and bits 8 or 16, got {} and {}",
                enc.gamma, enc.bits
            ),
        ));
    }
    let codes = ((1u32 << enc.bits) - 1) as f64;
    let inv = 1.0 / enc.gamma;
    let linear = |v: f64| 255.0 * v.clamp(0.0, 1.0).powf(inv);
    let k = captures.len() as f64;
    let mut out = Vec::with_capacity(c);
    for ch in 0..c {
        let planes: Vec<&[f32]> = captures.iter().map(|im| im.plane(ch)).collect();
        let (mut sum, mut var, mut quant, mut clipped) = (0.0f64, 0.0f64, 0.0f64, 0usize);
        let mut values = vec![0.0f64; captures.len()];
        for i in 0..h * w {
            let mut m = 0.0;
            for (v, p) in values.iter_mut().zip(&planes) {
                let code = (p[i] as f64 * codes).round();
                if code <= 0.0 || code >= codes {
                    clipped += 1;
                }
                // One code's linear size at this value: the quantisation's variance.
                let step = linear((code + 0.5) / codes) - linear((code - 0.5).max(0.0) / codes);
                quant += step * step / 12.0;
                *v = linear(code / codes);
                m += *v;
            }
            m /= k;
            sum += m;
            var += values.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / (k - 1.0);
        }
        let n = (h * w) as f64;
        let variance = var / n - quant / (n * k);
        let clipped = clipped as f64 / (n * k);
        let excluded = (clipped > MAX_CLIPPED).then(|| {
            format!(
                "{:.2} % of its samples at the lowest or highest code",
                100.0 * clipped
            )
        });
        out.push(Level {
            name: name.to_string(),
            channel: ch,
            captures: captures.len(),
            dof: h * w * (captures.len() - 1),
            mean: sum / n - dark.map_or(0.0, |d| d[ch.min(d.len() - 1)]),
            variance,
            quantisation: quant / (n * k),
            clipped,
            excluded,
        });
    }
    Ok(out)
}

/// Fits σ² = a·μ + b per channel and pooled over the channels, on the levels not excluded.
/// Needs at least three levels in each channel.
pub fn fit(levels: &[Level]) -> Result<Vec<NoiseFit>> {
    let channels = levels.iter().map(|l| l.channel + 1).max().unwrap_or(0);
    let used = |ch: Option<usize>| -> Vec<(f64, f64, usize)> {
        levels
            .iter()
            .filter(|l| l.excluded.is_none() && ch.is_none_or(|c| c == l.channel))
            .map(|l| (l.mean, l.variance, l.dof))
            .collect()
    };
    let mut fits = Vec::new();
    for ch in (0..channels).map(Some).chain(std::iter::once(None)) {
        let points = used(ch);
        if points.len() < 3 {
            return Err(Error::invalid(
                "captures",
                format!(
                    "{} has {} usable level(s); the fit needs at least 3 levels below clipping \
                     (exposures or brightnesses spread over the range)",
                    ch.map_or("the pooled fit".to_string(), |c| format!("channel {c}")),
                    points.len()
                ),
            ));
        }
        fits.push(NoiseFit {
            channel: ch,
            line: fit_line(&points)?,
        });
    }
    Ok(fits)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::imaging::pipeline::Camera;
    use crate::imaging::{CameraConfig, NoiseConfig, psf_source};

    /// Flats through pins's own camera at (a, b): `levels` scene intensities, `k` captures each.
    fn flats(a: f32, b: f32, bits: u8, levels: &[f32], k: usize) -> Vec<(String, Vec<Image>)> {
        let cfg = CameraConfig {
            noise: NoiseConfig {
                a,
                b,
                ..NoiseConfig::default()
            },
            bit_depth: bits,
            ..CameraConfig::default()
        };
        let (psf, _) = psf_source::load("delta").unwrap();
        let cam = Camera::new(&cfg, psf).unwrap();
        levels
            .iter()
            .enumerate()
            .map(|(i, &l)| {
                let scene = Image::filled(3, 96, 96, l);
                let caps = (0..k)
                    .map(|j| cam.apply(&scene, (100 * i + j) as u64).unwrap())
                    .collect();
                (format!("level{i:02}"), caps)
            })
            .collect()
    }

    fn recover(a: f32, b: f32, bits: u8) -> NoiseFit {
        let levels: Vec<f32> = (0..12).map(|i| 0.02 + 0.08 * i as f32).collect();
        let enc = Encoding { gamma: 1.7, bits };
        let stats: Vec<Level> = flats(a, b, bits, &levels, 4)
            .iter()
            .flat_map(|(n, caps)| level_stats(n, caps, enc, None).unwrap())
            .collect();
        let fits = fit(&stats).unwrap();
        assert_eq!(fits.len(), 4);
        fits.into_iter().find(|f| f.channel.is_none()).unwrap()
    }

    #[test]
    fn recovers_the_cameras_noise_over_two_orders_of_magnitude() {
        // The paper's noise, ten times less (at 16 bits, where 8-bit codes would swamp it) and
        // ten times more, each within 5 % and inside its own interval.
        for (a, b, bits) in [(0.2, 10.0, 8), (0.02, 1.0, 16), (2.0, 100.0, 8)] {
            let f = recover(a, b, bits).line;
            let (ea, eb) = ((f.a / a as f64 - 1.0).abs(), (f.b / b as f64 - 1.0).abs());
            assert!(ea < 0.05 && eb < 0.05, "a {a} b {b}: {f:?}");
            assert!(
                f.a_ci[0] <= a as f64 && a as f64 <= f.a_ci[1],
                "a {a} outside its interval: {f:?}"
            );
            assert!(
                f.b_ci[0] <= b as f64 && b as f64 <= f.b_ci[1],
                "b {b} outside its interval: {f:?}"
            );
        }
    }

    #[test]
    fn clipped_levels_are_left_out_and_bad_sets_are_named() {
        let caps = flats(0.2, 10.0, 8, &[0.0, 1.3], 2);
        let enc = Encoding {
            gamma: 1.7,
            bits: 8,
        };
        for (n, c) in &caps {
            for l in level_stats(n, c, enc, None).unwrap() {
                assert!(l.excluded.is_some(), "{l:?}");
            }
        }
        let one = level_stats("x", &caps[0].1[..1], enc, None).unwrap_err();
        assert!(one.to_string().contains("at least two"), "{one}");
        let mixed = [caps[0].1[0].clone(), Image::filled(3, 8, 8, 0.5)];
        let e = level_stats("x", &mixed, enc, None).unwrap_err();
        assert!(e.to_string().contains("differ in size"), "{e}");
        let few: Vec<Level> = flats(0.2, 10.0, 8, &[0.3, 0.5], 2)
            .iter()
            .flat_map(|(n, c)| level_stats(n, c, enc, None).unwrap())
            .collect();
        let e = fit(&few).unwrap_err().to_string();
        assert!(e.contains("at least 3 levels"), "{e}");
    }
}
