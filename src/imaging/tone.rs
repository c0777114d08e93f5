//! Tone stages: brightness scaling (Note S5's 20 % attenuation), clamp to [0, 1], the gamma
//! curve of Eq. S4, and quantisation to the sensor's bit depth.

use rayon::prelude::*;

use crate::types::Image;

/// Multiplies every sample by `k`.
pub fn scale(image: &mut Image, k: f32) {
    image.data_mut().par_iter_mut().for_each(|v| *v *= k);
}

/// Clamps every sample to [0, 1]; NaN becomes 0 so no later stage sees it.
pub fn clamp01(image: &mut Image) {
    image
        .data_mut()
        .par_iter_mut()
        .for_each(|v| *v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) });
}

/// Eq. S4, I_out = I_in^γ, on clamped input so that noise pushed below zero cannot make NaN.
pub fn gamma(image: &mut Image, g: f32) {
    image
        .data_mut()
        .par_iter_mut()
        .for_each(|v| *v = v.clamp(0.0, 1.0).powf(g));
}

/// Rounds every sample to the nearest of `2^bits` levels on [0, 1].
pub fn quantize(image: &mut Image, bits: u8) {
    let levels = ((1u32 << bits) - 1) as f32;
    image
        .data_mut()
        .par_iter_mut()
        .for_each(|v| *v = (v.clamp(0.0, 1.0) * levels).round() / levels);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gamma_is_eq_s4_and_safe_below_zero() {
        let mut im = Image::from_vec(1, 1, 4, vec![0.25, 1.0, -0.1, 0.0]).unwrap();
        gamma(&mut im, 1.7);
        assert!((im.data()[0] - 0.25f32.powf(1.7)).abs() < 1e-7);
        assert_eq!(&im.data()[1..], &[1.0, 0.0, 0.0]);
        for g in [1e-6f32, 50.0] {
            let mut im = Image::from_vec(1, 1, 3, vec![0.0, 0.5, 1.0]).unwrap();
            gamma(&mut im, g);
            assert!(
                im.data()
                    .iter()
                    .all(|v| v.is_finite() && (0.0..=1.0).contains(v))
            );
        }
    }

    #[test]
    fn quantize_and_clamp() {
        let mut im = Image::from_vec(1, 1, 4, vec![0.5, 1.5, f32::NAN, 0.001]).unwrap();
        clamp01(&mut im);
        assert_eq!(im.data(), &[0.5, 1.0, 0.0, 0.001]);
        quantize(&mut im, 8);
        assert_eq!(im.data(), &[128.0 / 255.0, 1.0, 0.0, 0.0]);
        let mut im = Image::from_vec(1, 1, 1, vec![0.001]).unwrap();
        quantize(&mut im, 16);
        assert_eq!(im.data()[0], 66.0 / 65535.0);
    }
}
