//! The camera configuration (Notes S4–S5): every default written once, as the paper fixes it.

use serde::{Deserialize, Serialize};

use super::convolve::ConvMethod;
use super::noise::NoiseConfig;
use crate::error::{Error, Result};

/// The camera model's parameters. Unknown JSON keys are rejected.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CameraConfig {
    /// Overall transmission of the metalens: the paper dims every image by 20 % (Note S5).
    pub brightness: f32,
    /// `"default"` (the shipped metalens PSF), `"delta"` (no blur), or a path to a PSF file
    /// (PNG 8/16-bit, EXR, .npy).
    pub psf: String,
    /// How the PSF convolution is computed.
    pub convolution: ConvMethod,
    /// Eq. S3 noise, a and b in 8-bit digital numbers.
    pub noise: NoiseConfig,
    /// Eq. S4 exponent.
    pub gamma: f32,
    /// Output quantisation: 8 or 16 bits.
    pub bit_depth: u8,
}

impl Default for CameraConfig {
    fn default() -> Self {
        Self {
            brightness: 0.8,
            psf: "default".into(),
            convolution: ConvMethod::Auto,
            noise: NoiseConfig::default(),
            gamma: 1.7,
            bit_depth: 8,
        }
    }
}

impl CameraConfig {
    /// Makes a relative PSF file path relative to `base` (the folder of the config file that
    /// named it) rather than to the caller's working directory.
    pub fn resolve_paths(&mut self, base: &std::path::Path) {
        if !matches!(self.psf.as_str(), "default" | "delta")
            && std::path::Path::new(&self.psf).is_relative()
        {
            self.psf = base.join(&self.psf).to_string_lossy().into_owned();
        }
    }

    /// Checks every value, naming the first one out of range.
    pub fn validate(&self) -> Result<()> {
        if !self.brightness.is_finite() || self.brightness < 0.0 {
            return Err(Error::invalid(
                "camera.brightness",
                format!("must be finite and >= 0, got {}", self.brightness),
            ));
        }
        if !self.gamma.is_finite() || self.gamma <= 0.0 {
            return Err(Error::invalid(
                "camera.gamma",
                format!("must be finite and > 0, got {}", self.gamma),
            ));
        }
        if self.bit_depth != 8 && self.bit_depth != 16 {
            return Err(Error::invalid(
                "camera.bit_depth",
                format!("must be 8 or 16, got {}", self.bit_depth),
            ));
        }
        if self.psf.trim().is_empty() {
            return Err(Error::invalid(
                "camera.psf",
                "empty; use \"default\", \"delta\" or a file path",
            ));
        }
        self.noise.validate()
    }

    /// A camera that changes nothing but quantisation: no dimming, blur, noise or gamma.
    pub fn ideal() -> Self {
        Self {
            brightness: 1.0,
            psf: "delta".into(),
            noise: NoiseConfig {
                a: 0.0,
                b: 0.0,
                ..NoiseConfig::default()
            },
            gamma: 1.0,
            ..Self::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_the_papers() {
        let c = CameraConfig::default();
        assert_eq!(
            (c.brightness, c.gamma, c.noise.a, c.noise.b),
            (0.8, 1.7, 0.2, 10.0)
        );
        c.validate().unwrap();
    }

    #[test]
    fn unknown_keys_and_bad_values_are_rejected() {
        let err = serde_json::from_str::<CameraConfig>(r#"{"gama": 1.5}"#).unwrap_err();
        assert!(err.to_string().contains("gama"), "{err}");
        let c: CameraConfig = serde_json::from_str(r#"{"gamma": 0}"#).unwrap();
        assert!(
            c.validate()
                .unwrap_err()
                .to_string()
                .contains("camera.gamma")
        );
        let c: CameraConfig = serde_json::from_str(r#"{"bit_depth": 12}"#).unwrap();
        assert!(c.validate().is_err());
        let c: CameraConfig = serde_json::from_str(r#"{"noise": {"a": -1}}"#).unwrap();
        assert!(c.validate().is_err());
    }
}
