//! Sensor spectral response (Notes S2, S4): R, G, B weights over sampled wavelengths for broadband PSFs.

/// One sampled wavelength and the relative response of the R, G and B pixels to it.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Band {
    /// Wavelength in nanometres.
    pub wavelength_nm: f64,
    /// Relative response `[R, G, B]` (non-negative; each channel is normalised later).
    pub rgb: [f64; 3],
}

/// Centres of the default R, G, B responses in nanometres.
pub const DEFAULT_CENTRES_NM: [f64; 3] = [610.0, 540.0, 460.0];
/// Standard deviation of each default Gaussian response in nanometres (FWHM ≈ 71 nm).
pub const DEFAULT_SIGMA_NM: f64 = 30.0;

/// The default sensor response: 420..=680 nm in 20 nm steps (14 samples), each channel a
/// Gaussian of σ = 30 nm centred at 610 (R), 540 (G) and 460 nm (B), under an equal-energy
/// (white) illuminant.
///
/// The paper does not publish its sensor curves; these approximate a typical RGB CMOS with a
/// Bayer filter and IR-cut filter (peaks near 600/530/460 nm, overlapping skirts). Only the
/// shape matters: every channel of the PSF is normalised to sum 1 afterwards.
pub fn default_bands() -> Vec<Band> {
    (0..14)
        .map(|i| {
            let wl = 420.0 + 20.0 * i as f64;
            let w =
                |c: f64| (-(wl - c).powi(2) / (2.0 * DEFAULT_SIGMA_NM * DEFAULT_SIGMA_NM)).exp();
            Band {
                wavelength_nm: wl,
                rgb: [
                    w(DEFAULT_CENTRES_NM[0]),
                    w(DEFAULT_CENTRES_NM[1]),
                    w(DEFAULT_CENTRES_NM[2]),
                ],
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_bands_cover_visible_with_peaks_in_order() {
        let b = default_bands();
        assert_eq!(b.len(), 14);
        assert_eq!(b[0].wavelength_nm, 420.0);
        assert_eq!(b[13].wavelength_nm, 680.0);
        let argmax = |c: usize| {
            b.iter()
                .max_by(|x, y| x.rgb[c].total_cmp(&y.rgb[c]))
                .unwrap()
                .wavelength_nm
        };
        let r = argmax(0);
        assert!(r == 600.0 || r == 620.0, "{r}"); // both 10 nm from 610
        assert_eq!(argmax(1), 540.0);
        assert_eq!(argmax(2), 460.0);
        assert!(
            b.iter()
                .all(|x| x.rgb.iter().all(|&w| (0.0..=1.0).contains(&w)))
        );
    }
}
