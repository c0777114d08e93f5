//! The 3-lens array on one sensor (Note S3, Fig. S3b): each lens's tilt (its viewing direction,
//! Note S2) and where its optical axis meets the 1600×1200 sensor, in a staggered,
//! non-overlapping layout; and the 480×1440 stitched image, one 45°×45° tile per lens.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::optics::Profile;

/// One lens of the array.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LensView {
    /// Tilt θt of the linear phase k·x·sin θt: the centre of the lens's horizontal sector.
    pub tilt_deg: f64,
    /// Sensor pixel `[x, y]` where the lens's optical axis lands.
    pub axis_px: [f64; 2],
}

/// The array: sensor, lenses, and the stitched output.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ArrayLayout {
    /// Sensor `[height, width]` in pixels.
    pub sensor: [usize; 2],
    pub pixel_um: f64,
    pub focal_mm: f64,
    pub profile: Profile,
    /// Horizontal and vertical field of each lens, degrees.
    pub tile_fov_deg: f64,
    /// Side of each square tile of the stitched image, pixels.
    pub tile_px: usize,
    pub lenses: Vec<LensView>,
}

impl Default for ArrayLayout {
    /// The paper's array: three 45° lenses tilted −45°, 0°, +45° on a 1600×1200 sensor. The
    /// side lenses sit high and the centre one low (staggered); their sub-images do not touch.
    fn default() -> Self {
        Self {
            sensor: [1200, 1600],
            pixel_um: 2.2,
            focal_mm: 1.6,
            profile: Profile::Hyperbolic,
            tile_fov_deg: 45.0,
            tile_px: 480,
            lenses: vec![
                LensView {
                    tilt_deg: -45.0,
                    axis_px: [172.0, 340.0],
                },
                LensView {
                    tilt_deg: 0.0,
                    axis_px: [800.0, 860.0],
                },
                LensView {
                    tilt_deg: 45.0,
                    axis_px: [1428.0, 340.0],
                },
            ],
        }
    }
}

impl ArrayLayout {
    /// Focal length in pixels.
    pub fn focal_px(&self) -> f64 {
        self.focal_mm * 1e3 / self.pixel_um
    }

    /// Size of the stitched image `[height, width]`.
    pub fn wide_size(&self) -> [usize; 2] {
        [self.tile_px, self.tile_px * self.lenses.len()]
    }

    /// Checks the values and that the lenses are ordered left to right.
    pub fn validate(&self) -> Result<()> {
        if self.sensor.iter().any(|&s| s == 0 || s > 20000)
            || self.tile_px == 0
            || self.tile_px > 8192
        {
            return Err(Error::invalid(
                "array layout",
                "sensor and tile sizes must be positive and sensible",
            ));
        }
        for (n, v) in [
            ("pixel_um", self.pixel_um),
            ("focal_mm", self.focal_mm),
            ("tile_fov_deg", self.tile_fov_deg),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::invalid(
                    format!("array.{n}"),
                    format!("must be finite and > 0, got {v}"),
                ));
            }
        }
        if self.tile_fov_deg >= 120.0 || self.lenses.is_empty() {
            return Err(Error::invalid(
                "array",
                "need at least one lens and a tile field below 120°",
            ));
        }
        if self
            .lenses
            .windows(2)
            .any(|w| w[0].tilt_deg >= w[1].tilt_deg)
        {
            return Err(Error::invalid(
                "array.lenses",
                "tilts must increase from left to right",
            ));
        }
        for l in &self.lenses {
            // Written so that NaN fails the check too.
            let edge = l.tilt_deg.abs() + self.tile_fov_deg / 2.0;
            if edge.is_nan() || edge >= 90.0 || l.axis_px.iter().any(|v| !v.is_finite()) {
                return Err(Error::invalid(
                    "array.lenses",
                    format!("lens at {}°: its sector must stay within ±90°", l.tilt_deg),
                ));
            }
        }
        Ok(())
    }
}
