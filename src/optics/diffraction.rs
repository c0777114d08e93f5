//! Note S2: broadband metalens PSF at the sensor by scalar diffraction, with chromatic defocus,
//! off-axis aberration and tilt, integrated into RGB sensor pixels.
//!
//! The metasurface imprints the design phase (in radians) at every wavelength (geometric
//! phase), so at λ it focuses at ≈ f λ0/λ: at 532 nm the spot is near the Airy limit
//! (~1 µm), while 450 / 650 nm light is spread over disks tens of pixels wide at the sensor
//! (z = f). Per wavelength: exact pupil phase + one 2D FFT ([`super::propagate`]), box
//! integration into pixels, normalisation to the whole fine window's energy; then weighting
//! by the [`Band`]s into R, G, B, each channel summed to 1, and an integer-pixel shift that
//! puts the design wavelength's centroid on the kernel centre (a shift-invariant blur: the
//! image position, i.e. distortion, is modelled elsewhere).
//!
//! Cost: one N×N complex FFT per wavelength (15 for the default bands), two at a time in
//! parallel with rayon, each using ≈ 100 MB at N = 2048. `compute_psf(&PsfParams::default())`
//! takes ≈ 1.2–2 s on 2 cores (see the ignored test `default_psf_runtime`).
//!
//! Measured with the default grid (N = 2048, 532 nm, 83.8 % radius, Airy 1.04 µm): hyperbolic
//! 1.07 µm on axis, 20 µm at 10°, 92 µm at 22.5°; quadratic 16.5 µm on axis (spherical
//! aberration at f/1.6), 108 µm at 22.5°. A flat sensor at z = f behind a single f/1.6
//! metasurface is sharp only near the axis; 40° needs grid ≥ 3328.

use super::lens::Lens;
use super::propagate::{Fine, Setup, fine_intensity};
use super::psf::Psf;
use super::sampling::{centroid, encircled_radius, integrate_pixels};
use super::spectrum::{Band, default_bands};
use crate::error::{Error, Result};
use crate::types::Image;
use rayon::prelude::*;

/// Fraction of the energy inside the first zero of an Airy pattern.
pub const AIRY_ENCIRCLED: f64 = 0.838;
/// Largest accepted kernel size.
pub const MAX_KERNEL: usize = 257;

/// What to compute: the lens, the field angle of the point source, the sensor kernel size,
/// the FFT grid and the spectral bands.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PsfParams {
    /// The metalens.
    pub lens: Lens,
    /// Field angle θ of the source in degrees, along +x (the image lands toward −x).
    pub field_angle_deg: f64,
    /// Kernel size K in sensor pixels (odd, 1..=257).
    pub kernel_size: usize,
    /// FFT grid N (even, 64..=8192); the pupil occupies about a quarter of it.
    pub grid: usize,
    /// Sampled wavelengths and their R, G, B weights.
    pub bands: Vec<Band>,
}

impl Default for PsfParams {
    fn default() -> Self {
        Self {
            lens: Lens::default(),
            field_angle_deg: 0.0,
            kernel_size: 65,
            grid: 2048,
            bands: default_bands(),
        }
    }
}

/// The PSF and its measured focal spot.
#[derive(Clone, Debug, PartialEq)]
pub struct PsfResult {
    /// The RGB kernel `[3, K, K]`, centred on the design wavelength's centroid.
    pub psf: Psf,
    /// Radius (µm) enclosing 83.8 % of the design-wavelength energy around its centroid. For a
    /// perfect lens this is within ~10 % of the Airy radius (the encircled energy is so flat
    /// near the first dark ring that sampling moves the 83.8 % point by a few percent).
    pub spot_radius_um: f64,
    /// Airy radius 1.22 λ0 f / D (µm) at the design wavelength.
    pub airy_radius_um: f64,
    /// Peak intensity of the design wavelength over that of an aberration-free lens.
    pub strehl_like: Option<f64>,
}

impl PsfParams {
    /// Fails, naming the field, on an invalid lens, angle, kernel, grid or band list.
    pub fn validate(&self) -> Result<()> {
        self.lens.validate()?;
        let a = self.field_angle_deg;
        if !(a.is_finite() && a.abs() < 90.0) {
            return Err(Error::invalid(
                "PSF field_angle_deg",
                format!("{a} is not a finite angle with |θ| < 90°"),
            ));
        }
        let k = self.kernel_size;
        if k.is_multiple_of(2) || k > MAX_KERNEL {
            return Err(Error::invalid(
                "PSF kernel_size",
                format!("{k} is not odd in 1..={MAX_KERNEL}"),
            ));
        }
        let n = self.grid;
        if n % 2 == 1 || !(64..=8192).contains(&n) {
            return Err(Error::invalid(
                "PSF grid",
                format!("{n} is not even in 64..=8192"),
            ));
        }
        if self.bands.is_empty() {
            return Err(Error::invalid("PSF bands", "the list is empty"));
        }
        for (i, b) in self.bands.iter().enumerate() {
            let wl = b.wavelength_nm;
            if !(wl.is_finite() && (200.0..=2000.0).contains(&wl)) {
                return Err(Error::invalid(
                    format!("PSF band {i}"),
                    format!("wavelength {wl} nm is outside 200..=2000 nm"),
                ));
            }
            if b.rgb.iter().any(|w| !(w.is_finite() && *w >= 0.0)) {
                return Err(Error::invalid(
                    format!("PSF band {i}"),
                    format!("weights {:?} must be finite and ≥ 0", b.rgb),
                ));
            }
        }
        for (c, name) in ["R", "G", "B"].iter().enumerate() {
            if self.bands.iter().map(|b| b.rgb[c]).sum::<f64>() <= 0.0 {
                return Err(Error::invalid(
                    "PSF bands",
                    format!("channel {name} has zero total weight"),
                ));
            }
        }
        Ok(())
    }

    fn design_m(&self) -> f64 {
        self.lens.design_wavelength_nm * 1e-9
    }

    /// Grid geometry holding a window of `window_px` pixels at `lambda_min_m`.
    fn setup(&self, window_px: usize, lambda_min_m: f64) -> Result<Setup> {
        let win = window_px as f64 * self.lens.pixel_um * 1e-6;
        Setup::new(
            &self.lens,
            self.field_angle_deg,
            self.grid,
            win,
            lambda_min_m,
        )
    }
}

/// The broadband RGB PSF of `params` (see the module notes).
pub fn compute_psf(params: &PsfParams) -> Result<PsfResult> {
    params.validate()?;
    let k = params.kernel_size;
    let pixel_m = params.lens.pixel_um * 1e-6;
    let design = params.design_m();
    let mut lambdas: Vec<f64> = params
        .bands
        .iter()
        .map(|b| b.wavelength_nm * 1e-9)
        .collect();
    let design_idx = match lambdas.iter().position(|&l| (l - design).abs() < 1e-12) {
        Some(i) => i,
        None => {
            lambdas.push(design);
            lambdas.len() - 1
        }
    };
    let lmin = lambdas.iter().cloned().fold(f64::INFINITY, f64::min);
    let s = params.setup(k + 2, lmin)?;
    // Pixel grid P = K + 2M: room for the recentring shift, within the smallest window.
    let win_px = s.n as f64 * s.out_pitch(lmin).1 / pixel_m;
    let margin = (k / 2).min((((win_px - k as f64) / 2.0).floor().max(0.0)) as usize);
    let p = k + 2 * margin;
    struct Out {
        pixels: Vec<f64>,
        spot: Option<(f64, Option<f64>)>,
    }
    let outs: Vec<Out> = lambdas
        .par_iter()
        .enumerate()
        .map(|(i, &l)| {
            let fine = fine_intensity(&s, &params.lens, l)?;
            let spot = (i == design_idx).then(|| (spot_of(&fine), Some(fine.peak_ratio)));
            Ok(Out {
                pixels: integrate_pixels(&fine, pixel_m, p),
                spot,
            })
        })
        .collect::<Result<_>>()?;
    // Integer-pixel shift putting the design wavelength's centroid on the centre.
    let dp = &outs[design_idx].pixels;
    let (mut mx, mut my, mut t) = (0.0, 0.0, 0.0);
    for (idx, &v) in dp.iter().enumerate() {
        mx += (idx % p) as f64 * v;
        my += (idx / p) as f64 * v;
        t += v;
    }
    let c = (p / 2) as f64;
    let m = margin as f64;
    let (sx, sy) = if t > 0.0 {
        (
            ((mx / t - c).round()).clamp(-m, m) as isize,
            ((my / t - c).round()).clamp(-m, m) as isize,
        )
    } else {
        (0, 0)
    };
    let (x0, y0) = (
        (margin as isize + sx) as usize,
        (margin as isize + sy) as usize,
    );
    let mut data = vec![0f32; 3 * k * k];
    for ch in 0..3 {
        let mut acc = vec![0f64; k * k];
        for (b, band) in params.bands.iter().enumerate() {
            let wgt = band.rgb[ch];
            if wgt == 0.0 {
                continue;
            }
            let px = &outs[b].pixels;
            for y in 0..k {
                for x in 0..k {
                    acc[y * k + x] += wgt * px[(y0 + y) * p + x0 + x];
                }
            }
        }
        let sum: f64 = acc.iter().sum();
        if sum.is_nan() || sum <= 0.0 {
            return Err(Error::invalid(
                "PSF",
                format!("channel {ch} collected no light inside the {k}×{k} kernel"),
            ));
        }
        for (d, a) in data[ch * k * k..(ch + 1) * k * k].iter_mut().zip(&acc) {
            *d = (a / sum) as f32;
        }
    }
    let psf = Psf::from_image(Image::from_vec(3, k, k, data)?, "computed PSF")?;
    let (spot, strehl) = outs[design_idx].spot.expect("design wavelength computed");
    Ok(PsfResult {
        psf,
        spot_radius_um: spot * 1e6,
        airy_radius_um: params.lens.airy_radius_um(params.lens.design_wavelength_nm),
        strehl_like: strehl,
    })
}

/// Focal-spot radius (µm) at `wavelength_nm` for the lens and field angle of `params`: the
/// radius enclosing 83.8 % of the energy around the centroid (the Airy first-zero radius for
/// a perfect lens). Uses `params.grid` and `params.kernel_size`; ignores the bands.
pub fn spot_radius_um(params: &PsfParams, wavelength_nm: f64) -> Result<f64> {
    params.validate()?;
    if !(wavelength_nm.is_finite() && (200.0..=2000.0).contains(&wavelength_nm)) {
        return Err(Error::invalid(
            "spot wavelength",
            format!("{wavelength_nm} nm is outside 200..=2000 nm"),
        ));
    }
    let l = wavelength_nm * 1e-9;
    let s = params.setup(params.kernel_size + 2, l)?;
    let fine = fine_intensity(&s, &params.lens, l)?;
    Ok(spot_of(&fine) * 1e6)
}

fn spot_of(fine: &Fine) -> f64 {
    encircled_radius(fine, centroid(fine), AIRY_ENCIRCLED)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optics::Profile;

    const K: usize = 55;

    /// A 5× smaller lens with the paper's f-number: same Airy spot, 5× smaller colour disks,
    /// so a 512 grid suffices; 1.1 µm pixels keep the blur-to-pixel ratio closer to the paper's.
    fn small(profile: Profile, field: f64) -> PsfParams {
        PsfParams {
            lens: Lens {
                diameter_mm: 0.2,
                focal_mm: 0.32,
                pixel_um: 1.1,
                profile,
                ..Lens::default()
            },
            field_angle_deg: field,
            kernel_size: K,
            grid: 512,
            bands: default_bands(),
        }
    }

    fn second_moment(p: &[f32], k: usize) -> f64 {
        let c = (k / 2) as f64;
        p.iter()
            .enumerate()
            .map(|(i, &v)| v as f64 * (((i % k) as f64 - c).powi(2) + ((i / k) as f64 - c).powi(2)))
            .sum()
    }

    #[test]
    fn on_axis_psf_is_normalised_symmetric_and_sharp_in_green() {
        let r = compute_psf(&small(Profile::Hyperbolic, 0.0)).unwrap();
        let k = K;
        assert_eq!(r.psf.size(), (k, k));
        for c in 0..3 {
            let p = r.psf.channel(c);
            let s: f64 = p.iter().map(|&v| v as f64).sum();
            assert!((s - 1.0).abs() < 1e-5, "channel {c} sums to {s}");
            let peak = p.iter().cloned().fold(0.0, f32::max);
            for y in 0..k {
                for x in 0..k {
                    let v = p[y * k + x];
                    assert!(
                        (v - p[y * k + k - 1 - x]).abs() <= 1e-3 * peak,
                        "x mirror c{c} {y},{x}"
                    );
                    assert!(
                        (v - p[(k - 1 - y) * k + x]).abs() <= 1e-3 * peak,
                        "y mirror c{c} {y},{x}"
                    );
                }
            }
        }
        let rel = r.spot_radius_um / r.airy_radius_um;
        assert!(
            (rel - 1.0).abs() < 0.15,
            "spot {} vs Airy {}",
            r.spot_radius_um,
            r.airy_radius_um
        );
        assert!(r.strehl_like.unwrap() > 0.95, "{:?}", r.strehl_like);
        let m: Vec<f64> = (0..3).map(|c| second_moment(r.psf.channel(c), k)).collect();
        assert!(
            m[0] > 4.0 * m[1] && m[2] > 4.0 * m[1],
            "second moments R G B {m:?}"
        );
    }

    #[test]
    fn quadratic_spot_grows_off_axis() {
        let on = spot_radius_um(&small(Profile::Quadratic, 0.0), 532.0).unwrap();
        let off = spot_radius_um(&small(Profile::Quadratic, 20.0), 532.0).unwrap();
        assert!(off > on, "0°: {on} µm, 20°: {off} µm");
        let hyp = spot_radius_um(&small(Profile::Hyperbolic, 20.0), 532.0).unwrap();
        assert!(
            hyp > 1.5 * Lens::default().airy_radius_um(532.0),
            "hyperbolic 20°: {hyp}"
        );
    }

    #[test]
    fn tilt_moves_the_best_field_angle() {
        let mut p = small(Profile::Hyperbolic, 20.0);
        p.lens.tilt_deg = 20.0;
        let r = compute_psf(&p).unwrap();
        assert!(
            (r.spot_radius_um / r.airy_radius_um - 1.0).abs() < 0.15,
            "{}",
            r.spot_radius_um
        );
    }

    #[test]
    fn too_coarse_grid_is_an_error() {
        let mut p = small(Profile::Hyperbolic, 0.0);
        p.kernel_size = 9;
        p.grid = 192;
        let e = compute_psf(&p).unwrap_err().to_string();
        assert!(e.contains("too coarse") && e.contains("grid ≥"), "{e}");
        let p = PsfParams {
            grid: 128,
            ..PsfParams::default()
        };
        let e = compute_psf(&p).unwrap_err().to_string();
        assert!(e.contains("cannot hold") && e.contains("grid ≥"), "{e}");
    }

    #[test]
    fn invalid_params_are_errors() {
        let bad = |f: fn(&mut PsfParams)| {
            let mut p = small(Profile::Hyperbolic, 0.0);
            f(&mut p);
            compute_psf(&p).unwrap_err().to_string()
        };
        assert!(bad(|p| p.lens.focal_mm = -1.0).contains("focal_mm"));
        assert!(bad(|p| p.lens.tilt_deg = f64::INFINITY).contains("tilt_deg"));
        assert!(bad(|p| p.field_angle_deg = 95.0).contains("field_angle_deg"));
        assert!(bad(|p| p.kernel_size = 32).contains("kernel_size"));
        assert!(bad(|p| p.kernel_size = 259).contains("kernel_size"));
        assert!(bad(|p| p.grid = 511).contains("grid"));
        assert!(bad(|p| p.bands.clear()).contains("bands"));
        assert!(bad(|p| p.bands[0].rgb[1] = f64::NAN).contains("band 0"));
        assert!(bad(|p| p.bands.iter_mut().for_each(|b| b.rgb[2] = 0.0)).contains("channel B"));
        assert!(spot_radius_um(&small(Profile::Quadratic, 0.0), 5000.0).is_err());
    }

    /// The full default: N = 2048, K = 65, paper lens. Run with
    /// `cargo test --release default_psf_runtime -- --ignored --nocapture`.
    #[test]
    #[ignore = "system tier (cargo test --release -- --ignored): the full-size default PSF"]
    fn default_psf_runtime() {
        let t = std::time::Instant::now();
        let r = compute_psf(&PsfParams::default()).unwrap();
        println!("compute_psf(default): {:.2} s", t.elapsed().as_secs_f64());
        println!(
            "spot {:.3} µm, Airy {:.3} µm, strehl {:?}",
            r.spot_radius_um, r.airy_radius_um, r.strehl_like
        );
        let k = 65;
        for c in 0..3 {
            println!(
                "channel {c}: second moment {:.1} px²",
                second_moment(r.psf.channel(c), k)
            );
        }
        assert!((r.spot_radius_um / r.airy_radius_um - 1.0).abs() < 0.15);
        for profile in [Profile::Hyperbolic, Profile::Quadratic] {
            let p = PsfParams {
                lens: Lens {
                    profile,
                    ..Lens::default()
                },
                field_angle_deg: 22.5,
                ..PsfParams::default()
            };
            let t = std::time::Instant::now();
            let r = compute_psf(&p).unwrap();
            println!(
                "{profile:?} 22.5° compute_psf: {:.2} s, spot {:.2} µm",
                t.elapsed().as_secs_f64(),
                r.spot_radius_um
            );
            for angle in [0.0, 10.0, 22.5, 30.0, 40.0] {
                let p = PsfParams {
                    lens: Lens {
                        profile,
                        ..Lens::default()
                    },
                    field_angle_deg: angle,
                    ..PsfParams::default()
                };
                match spot_radius_um(&p, 532.0) {
                    Ok(s) => println!(
                        "{profile:?} {angle:>5}°: spot {s:.3} µm = {:.2} Airy",
                        s / r.airy_radius_um
                    ),
                    Err(e) => println!("{profile:?} {angle:>5}°: {e}"),
                }
            }
        }
    }
}
