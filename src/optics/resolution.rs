//! Detection limits (Note S12, Fig. S10h): the angle one pixel subtends, and what that means in
//! metres at a distance for the smallest detectable displacement and target.

use serde::Serialize;

use crate::error::{Error, Result};

/// The limits at one object distance.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Resolution {
    /// Angle of one pixel, p/f, in mrad and degrees.
    pub pixel_angle_mrad: f64,
    pub pixel_angle_deg: f64,
    pub distance_m: f64,
    /// Size in the scene of one pixel at that distance, m.
    pub pixel_footprint_m: f64,
    /// Smallest displacement detected (Note S12: 3 px), in m at that distance.
    pub min_displacement_m: f64,
    /// Smallest object detected (Note S12: a 5-px-diameter target), in m at that distance.
    pub min_object_m: f64,
}

/// From pixel pitch (µm), focal length (mm), distance (m), and the smallest detectable
/// displacement and target diameter in pixels.
pub fn resolution(
    pixel_um: f64,
    focal_mm: f64,
    distance_m: f64,
    min_shift_px: f64,
    min_target_px: f64,
) -> Result<Resolution> {
    for (n, v) in [
        ("pixel", pixel_um),
        ("focal length", focal_mm),
        ("distance", distance_m),
        ("displacement", min_shift_px),
        ("target size", min_target_px),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(Error::invalid(
                n,
                format!("must be finite and > 0, got {v}"),
            ));
        }
    }
    // Small-angle (exact on axis): one pixel spans atan(p/f).
    let angle = (pixel_um * 1e-6 / (focal_mm * 1e-3)).atan();
    let footprint = distance_m * angle.tan();
    Ok(Resolution {
        pixel_angle_mrad: angle * 1e3,
        pixel_angle_deg: angle.to_degrees(),
        distance_m,
        pixel_footprint_m: footprint,
        min_displacement_m: footprint * min_shift_px,
        min_object_m: footprint * min_target_px,
    })
}

#[cfg(test)]
mod tests {
    #[test]
    fn paper_lens_at_ten_metres() {
        let r = super::resolution(2.2, 1.6, 10.0, 3.0, 5.0).unwrap();
        assert!((r.pixel_angle_mrad - 1.375).abs() < 1e-3);
        assert!((r.pixel_angle_deg - 0.0788).abs() < 1e-3);
        // Note S12: about 4 cm of displacement at 10 m (3 px).
        assert!((r.min_displacement_m - 0.041).abs() < 0.002);
        assert!(super::resolution(2.2, 0.0, 10.0, 3.0, 5.0).is_err());
    }
}
