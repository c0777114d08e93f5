//! The metalens of Note S2: aperture, focal length, pixel pitch, design wavelength, phase profile and tilt.

use crate::error::{Error, Result};

/// The phase profile the metasurface imprints (Note S2, Fig. S2a; see [`crate::optics::phase::phase`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Profile {
    /// φ(r) = −(2π/λ)(√(r²+f²) − f): a perfect on-axis focus, coma off axis.
    Hyperbolic,
    /// φ(r) = −π r²/(λ f): spherical aberration on axis, but nearly shift-invariant over wide angles.
    Quadratic,
}

/// One metalens on the sensor. Defaults are the paper's: D = 1 mm, f = 1.6 mm, 2.2 µm pixels,
/// designed at 532 nm, hyperbolic profile, no tilt.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Lens {
    /// Aperture (pupil) diameter D in millimetres.
    pub diameter_mm: f64,
    /// Design focal length f in millimetres; the sensor sits at z = f.
    pub focal_mm: f64,
    /// Sensor pixel pitch in micrometres.
    pub pixel_um: f64,
    /// Wavelength λ0 at which the phase profile is designed, in nanometres.
    pub design_wavelength_nm: f64,
    /// Hyperbolic or quadratic phase profile.
    pub profile: Profile,
    /// Linear tilt-phase angle θt in degrees (Note S2, Fig. S2b: `k x sin θt`); positive values
    /// move the viewing direction toward +x field angles.
    pub tilt_deg: f64,
}

impl Default for Lens {
    fn default() -> Self {
        Self {
            diameter_mm: 1.0,
            focal_mm: 1.6,
            pixel_um: 2.2,
            design_wavelength_nm: 532.0,
            profile: Profile::Hyperbolic,
            tilt_deg: 0.0,
        }
    }
}

impl Lens {
    /// Fails, naming the field, unless sizes are positive and finite, |tilt| < 90° and the
    /// design wavelength lies in 200..=2000 nm.
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [
            ("lens diameter_mm", self.diameter_mm),
            ("lens focal_mm", self.focal_mm),
            ("lens pixel_um", self.pixel_um),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::invalid(
                    name,
                    format!("{v} is not a positive finite number"),
                ));
            }
        }
        let wl = self.design_wavelength_nm;
        if !(wl.is_finite() && (200.0..=2000.0).contains(&wl)) {
            return Err(Error::invalid(
                "lens design_wavelength_nm",
                format!("{wl} nm is outside 200..=2000 nm"),
            ));
        }
        if !(self.tilt_deg.is_finite() && self.tilt_deg.abs() < 90.0) {
            return Err(Error::invalid(
                "lens tilt_deg",
                format!("{} is not a finite angle with |tilt| < 90°", self.tilt_deg),
            ));
        }
        Ok(())
    }

    /// Airy-disk radius (first zero) 1.22 λ f / D in micrometres, for `lambda_nm` in nanometres.
    pub fn airy_radius_um(&self, lambda_nm: f64) -> f64 {
        1.22 * lambda_nm * 1e-3 * self.focal_mm / self.diameter_mm
    }

    /// Working f-number f / D.
    pub fn f_number(&self) -> f64 {
        self.focal_mm / self.diameter_mm
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_the_papers() {
        let l = Lens::default();
        l.validate().unwrap();
        assert!((l.f_number() - 1.6).abs() < 1e-12);
        // 1.22 · 0.532 µm · 1.6 = 1.0385 µm: under one 2.2 µm pixel.
        assert!((l.airy_radius_um(532.0) - 1.038464).abs() < 1e-6);
    }

    #[test]
    fn invalid_values_are_named() {
        let bad = |f: fn(&mut Lens)| {
            let mut l = Lens::default();
            f(&mut l);
            l.validate().unwrap_err().to_string()
        };
        assert!(bad(|l| l.diameter_mm = 0.0).contains("diameter_mm"));
        assert!(bad(|l| l.focal_mm = f64::NAN).contains("focal_mm"));
        assert!(bad(|l| l.pixel_um = -2.2).contains("pixel_um"));
        assert!(bad(|l| l.design_wavelength_nm = 150.0).contains("design_wavelength_nm"));
        assert!(bad(|l| l.tilt_deg = 90.0).contains("tilt_deg"));
    }

    #[test]
    fn serde_round_trip_lowercase_profile() {
        let l = Lens {
            profile: Profile::Quadratic,
            ..Lens::default()
        };
        let s = serde_json::to_string(&l).unwrap();
        assert!(s.contains("\"quadratic\""), "{s}");
        let back: Lens = serde_json::from_str(&s).unwrap();
        assert_eq!(back, l);
        let partial: Lens = serde_json::from_str(r#"{"tilt_deg": 45}"#).unwrap();
        assert_eq!(partial.focal_mm, 1.6);
        assert!(serde_json::from_str::<Lens>(r#"{"focus": 1}"#).is_err());
    }
}
