//! Where the camera's PSF comes from: the shipped metalens PSF (computed by scalar diffraction,
//! Note S2), no blur, or a measured PSF read from a file (PNG 8/16-bit, EXR, .npy, TIFF).

use std::path::Path;

use crate::error::{Error, Result};
use crate::io;
use crate::optics::Psf;

/// The shipped default: the broadband RGB PSF of the paper's hyperbolic metalens (D = 1 mm,
/// f = 1.6 mm, designed for 532 nm, on-axis), as written by
/// `pins psf --out datasets/psf/metalens_default.npy`.
pub const DEFAULT_PSF_NPY: &[u8] = include_bytes!("../../datasets/psf/metalens_default.npy");

/// Path of the shipped default inside the repository, for messages.
pub const DEFAULT_PSF_PATH: &str = "datasets/psf/metalens_default.npy";

/// Resolves `"default"`, `"delta"` or a file path into a validated, normalised PSF and a
/// one-line description for manifests.
pub fn load(spec: &str) -> Result<(Psf, String)> {
    match spec {
        "default" => {
            let img = io::npy::decode_npy(DEFAULT_PSF_NPY, Path::new(DEFAULT_PSF_PATH))?;
            let psf = Psf::from_image(img, DEFAULT_PSF_PATH)?;
            let ((h, w), c) = (psf.size(), psf.channels());
            Ok((psf, format!("default ({DEFAULT_PSF_PATH}, {c}x{h}x{w})")))
        }
        "delta" => Ok((Psf::delta(3), "delta (no blur)".into())),
        path => {
            let p = Path::new(path);
            if !p.is_file() {
                return Err(Error::invalid(
                    "PSF",
                    format!("{path:?} is neither \"default\", \"delta\" nor an existing file"),
                ));
            }
            let img = io::read_image(p)?;
            let psf = Psf::from_image(img, path)?;
            let ((h, w), c) = (psf.size(), psf.channels());
            Ok((psf, format!("file {path} ({c}x{h}x{w})")))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::types::Image;

    #[test]
    fn default_psf_is_a_real_blur() {
        let (psf, desc) = load("default").unwrap();
        assert_eq!(psf.channels(), 3);
        assert!(!psf.is_delta());
        assert!(desc.contains("default"));
        for c in 0..3 {
            let s: f64 = psf.channel(c).iter().map(|&v| v as f64).sum();
            assert!((s - 1.0).abs() < 1e-4);
        }
    }

    #[test]
    fn bad_psf_files_are_rejected_with_their_name() {
        let d = tempfile::tempdir().unwrap();
        assert!(load(d.path().join("none.png").to_str().unwrap()).is_err());
        let mut img = Image::filled(1, 5, 5, 0.1);
        img.set(0, 2, 2, f32::NAN);
        let p = d.path().join("nan.npy");
        io::write_npy(&p, &img).unwrap();
        let err = load(p.to_str().unwrap()).unwrap_err().to_string();
        assert!(err.contains("nan.npy"), "{err}");
        let p = d.path().join("zero.npy");
        io::write_npy(&p, &Image::zeros(1, 5, 5)).unwrap();
        assert!(load(p.to_str().unwrap()).is_err());
    }
}
