//! `Psf`: a normalised, centred, odd-sized blur kernel `[C, h, w]` (the PSF of Note S2 as used by Note S4).

use crate::error::{Error, Result};
use crate::types::Image;

/// A point-spread function `[C, h, w]`: finite, non-negative, odd `h` and `w`, centred on
/// `(h/2, w/2)`, every channel summing to 1.
#[derive(Clone, Debug, PartialEq)]
pub struct Psf {
    image: Image,
}

impl Psf {
    /// Validates and normalises a kernel image; `what` names it in errors.
    ///
    /// Rejects empty kernels, channel counts other than 1 (grey) or 3 (RGB), even heights or
    /// widths (an even kernel has no centre pixel, so where the blur is centred would be a
    /// guess: half a pixel of shift in every image), non-finite or negative samples and
    /// channels summing to 0. Each channel is then scaled to sum 1 (sums in f64).
    pub fn from_image(img: Image, what: &str) -> Result<Psf> {
        let (c, h, w) = img.shape();
        if c == 0 || h == 0 || w == 0 {
            return Err(Error::invalid(
                what,
                format!("empty PSF of shape {c}x{h}x{w}"),
            ));
        }
        if c != 1 && c != 3 {
            return Err(Error::invalid(
                what,
                format!("a PSF has 1 (grey) or 3 (RGB) channels, this one has {c}"),
            ));
        }
        if h % 2 == 0 || w % 2 == 0 {
            return Err(Error::invalid(
                what,
                format!(
                    "a PSF needs an odd width and height so that its centre is a pixel, \
                     this one is {w}x{h}; crop it (or pad one row/column of zeros) around \
                     the pixel that should be the centre"
                ),
            ));
        }
        img.check_finite(what)?;
        if let Some(i) = img.data().iter().position(|&v| v < 0.0) {
            let n = h * w;
            return Err(Error::invalid(
                what,
                format!(
                    "negative value {} at channel {}, row {}, column {}",
                    img.data()[i],
                    i / n,
                    (i % n) / w,
                    i % w
                ),
            ));
        }
        let mut out = Image::zeros(c, h, w);
        for ch in 0..c {
            let src = img.plane(ch);
            let sum: f64 = src.iter().map(|&v| v as f64).sum();
            if !sum.is_finite() || sum <= 0.0 {
                return Err(Error::invalid(
                    what,
                    format!("channel {ch} sums to {sum}, not a positive number"),
                ));
            }
            let dst = out.plane_mut(ch);
            for y in 0..h {
                for x in 0..w {
                    dst[y * w + x] = (src[y * w + x] as f64 / sum) as f32;
                }
            }
        }
        Ok(Psf { image: out })
    }

    /// The identity kernel `[channels, 1, 1]` (0 channels are treated as 1).
    pub fn delta(channels: usize) -> Psf {
        Psf {
            image: Image::filled(channels.max(1), 1, 1, 1.0),
        }
    }

    /// A sampled isotropic Gaussian of standard deviation `sigma_px` pixels on a `size`×`size`
    /// grid, identical in every channel. `size` must be odd; `sigma_px` = 0 gives a delta of
    /// that size.
    pub fn gaussian(channels: usize, sigma_px: f64, size: usize) -> Result<Psf> {
        if channels == 0 {
            return Err(Error::invalid(
                "gaussian PSF channels",
                "must be at least 1",
            ));
        }
        if size.is_multiple_of(2) {
            return Err(Error::invalid(
                "gaussian PSF size",
                format!("{size} is not odd"),
            ));
        }
        if !(sigma_px.is_finite() && sigma_px >= 0.0) {
            return Err(Error::invalid(
                "gaussian PSF sigma_px",
                format!("{sigma_px} is not a finite number ≥ 0"),
            ));
        }
        let r = (size / 2) as f64;
        let mut plane = vec![0f32; size * size];
        for y in 0..size {
            for x in 0..size {
                let (dy, dx) = (y as f64 - r, x as f64 - r);
                plane[y * size + x] = if sigma_px == 0.0 {
                    (dx == 0.0 && dy == 0.0) as u8 as f32
                } else {
                    (-(dx * dx + dy * dy) / (2.0 * sigma_px * sigma_px)).exp() as f32
                };
            }
        }
        let data = plane.repeat(channels);
        Psf::from_image(Image::from_vec(channels, size, size, data)?, "gaussian PSF")
    }

    /// True when every channel has all its energy in the centre sample.
    pub fn is_delta(&self) -> bool {
        let (h, w) = self.size();
        let centre = (h / 2) * w + w / 2;
        (0..self.channels()).all(|c| (self.channel(c)[centre] - 1.0).abs() < 1e-6)
    }

    /// Number of channels C.
    pub fn channels(&self) -> usize {
        self.image.channels()
    }

    /// `(h, w)`, both odd.
    pub fn size(&self) -> (usize, usize) {
        (self.image.height(), self.image.width())
    }

    /// The kernel as an image `[C, h, w]`.
    pub fn image(&self) -> &Image {
        &self.image
    }

    /// Channel `c` as a row-major `[h, w]` plane. Panics if `c >= channels()`.
    pub fn channel(&self, c: usize) -> &[f32] {
        self.image.plane(c)
    }

    /// The kernel a monochrome sensor sees: the mean of the channels, renormalised, `[1, h, w]`.
    pub fn to_mono(&self) -> Psf {
        let (h, w) = self.size();
        let c = self.channels();
        let mut acc = vec![0f64; h * w];
        for ch in 0..c {
            for (a, &v) in acc.iter_mut().zip(self.channel(ch)) {
                *a += v as f64;
            }
        }
        let sum: f64 = acc.iter().sum();
        let data = acc.iter().map(|&v| (v / sum) as f32).collect();
        Psf {
            image: Image::from_vec(1, h, w, data).expect("shape is consistent"),
        }
    }

    /// The smallest centred odd square holding at least `frac` of every channel's energy,
    /// renormalised. `frac` is clamped to (0, 1]; NaN means 1. Never larger than the kernel
    /// (a non-square kernel is cropped per axis to at most its own size).
    pub fn crop_energy(&self, frac: f64) -> Psf {
        let frac = if frac.is_nan() {
            1.0
        } else {
            frac.clamp(1e-12, 1.0)
        };
        let (h, w) = self.size();
        let (cy, cx) = (h / 2, w / 2);
        let max_r = cy.max(cx);
        let mut radius = max_r;
        'search: for r in 0..=max_r {
            let (ry, rx) = (r.min(cy), r.min(cx));
            for c in 0..self.channels() {
                let p = self.channel(c);
                let mut e = 0f64;
                for y in cy - ry..=cy + ry {
                    e += p[y * w + cx - rx..=y * w + cx + rx]
                        .iter()
                        .map(|&v| v as f64)
                        .sum::<f64>();
                }
                // Channels sum to 1 in f64 only up to f32 rounding: allow a small slack.
                if e < frac - 1e-6 {
                    continue 'search;
                }
            }
            radius = r;
            break;
        }
        let (ry, rx) = (radius.min(cy), radius.min(cx));
        let (nh, nw) = (2 * ry + 1, 2 * rx + 1);
        let mut out = Image::zeros(self.channels(), nh, nw);
        for c in 0..self.channels() {
            let p = self.channel(c);
            let sum: f64 = (cy - ry..=cy + ry)
                .flat_map(|y| p[y * w + cx - rx..=y * w + cx + rx].iter())
                .map(|&v| v as f64)
                .sum();
            let dst = out.plane_mut(c);
            for (yy, y) in (cy - ry..=cy + ry).enumerate() {
                for (xx, x) in (cx - rx..=cx + rx).enumerate() {
                    dst[yy * nw + xx] = (p[y * w + x] as f64 / sum) as f32;
                }
            }
        }
        Psf { image: out }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sum(p: &[f32]) -> f64 {
        p.iter().map(|&v| v as f64).sum()
    }

    #[test]
    fn rejects_bad_kernels() {
        let mut im = Image::filled(3, 3, 3, 1.0);
        im.set(1, 2, 0, f32::NAN);
        assert!(
            Psf::from_image(im, "k")
                .unwrap_err()
                .to_string()
                .contains("non-finite")
        );
        let mut im = Image::filled(1, 3, 3, 1.0);
        im.set(0, 1, 1, -0.5);
        assert!(
            Psf::from_image(im, "k")
                .unwrap_err()
                .to_string()
                .contains("negative")
        );
        let mut im = Image::filled(3, 3, 3, 1.0);
        im.plane_mut(1).fill(0.0);
        assert!(
            Psf::from_image(im, "k")
                .unwrap_err()
                .to_string()
                .contains("channel 1")
        );
        assert!(Psf::from_image(Image::zeros(1, 0, 3), "k").is_err());
    }

    #[test]
    fn normalises_and_refuses_even_sizes_and_odd_channel_counts() {
        let im = Image::from_vec(1, 3, 1, vec![1.0, 2.0, 3.0]).unwrap();
        let p = Psf::from_image(im, "k").unwrap();
        assert_eq!(p.size(), (3, 1));
        assert!((sum(p.channel(0)) - 1.0).abs() < 1e-6);
        assert!((p.channel(0)[2] - 0.5).abs() < 1e-7);
        for (c, h, w) in [(1, 2, 3), (3, 4, 4), (3, 9, 8)] {
            let err = Psf::from_image(Image::filled(c, h, w, 2.0), "k")
                .unwrap_err()
                .to_string();
            assert!(err.contains("odd width and height"), "{err}");
        }
        for c in [2, 4] {
            let err = Psf::from_image(Image::filled(c, 3, 3, 1.0), "k")
                .unwrap_err()
                .to_string();
            assert!(err.contains("1 (grey) or 3 (RGB) channels"), "{err}");
        }
    }

    #[test]
    fn delta_gaussian_mono_crop() {
        assert!(Psf::delta(3).is_delta());
        assert_eq!(Psf::delta(0).channels(), 1);
        assert!(Psf::gaussian(3, 0.0, 5).unwrap().is_delta());
        assert!(Psf::gaussian(1, 1.0, 4).is_err());
        assert!(Psf::gaussian(1, f64::NAN, 5).is_err());
        let g = Psf::gaussian(3, 1.5, 15).unwrap();
        assert!(!g.is_delta());
        let m = g.to_mono();
        assert_eq!(m.channels(), 1);
        assert!((sum(m.channel(0)) - 1.0).abs() < 1e-6);
        // 2D Gaussian: energy within ±2.5σ square ≈ 0.9876² ≈ 0.975.
        let c = g.crop_energy(0.95);
        assert!(c.size().0 < 15 && c.size().0 % 2 == 1, "{:?}", c.size());
        assert!((sum(c.channel(2)) - 1.0).abs() < 1e-6);
        assert_eq!(g.crop_energy(1.0).size(), (15, 15));
        assert_eq!(g.crop_energy(f64::NAN).size(), (15, 15));
        assert_eq!(Psf::delta(1).crop_energy(0.5).size(), (1, 1));
    }
}
