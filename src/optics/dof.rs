//! Depth of field (Note S6, Eqs. S5–S8): with the sensor at v0 behind a lens of focal length f,
//! objects stay acceptably sharp while their image lies within ±Δv_max = c·F/# of the sensor,
//! with the circle of confusion c = 2 pixels and F/# = f/D.

use serde::Serialize;

use crate::error::{Error, Result};

/// The object-distance range in focus for one sensor distance.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DofRow {
    /// v0 − f in µm.
    pub v0_minus_f_um: f64,
    /// Near limit in m.
    pub u_near_m: f64,
    /// Far limit in m; `None` is infinity.
    pub u_far_m: Option<f64>,
}

/// Lens and sensor of the calculation (paper values by default).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DofParams {
    pub focal_mm: f64,
    pub diameter_mm: f64,
    pub pixel_um: f64,
    /// Circle of confusion in pixels (the paper takes 2).
    pub coc_pixels: f64,
}

impl Default for DofParams {
    fn default() -> Self {
        Self {
            focal_mm: 1.6,
            diameter_mm: 1.0,
            pixel_um: 2.2,
            coc_pixels: 2.0,
        }
    }
}

impl DofParams {
    /// Δv_max = c · F/# in metres (7.04 µm for the paper's lens).
    pub fn max_shift_m(&self) -> f64 {
        self.coc_pixels * self.pixel_um * 1e-6 * self.focal_mm / self.diameter_mm
    }

    fn validate(&self) -> Result<()> {
        for (n, v) in [
            ("focal length", self.focal_mm),
            ("diameter", self.diameter_mm),
            ("pixel", self.pixel_um),
            ("circle of confusion", self.coc_pixels),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::invalid(
                    n,
                    format!("must be finite and > 0, got {v}"),
                ));
            }
        }
        Ok(())
    }

    /// Eq. S8 for a sensor at v0 = f + `offset_um`; the far limit is infinite when
    /// v0 − Δv_max ≤ f. A sensor closer than f − Δv_max focuses nothing (an error).
    pub fn range(&self, offset_um: f64) -> Result<DofRow> {
        self.validate()?;
        if !offset_um.is_finite() {
            return Err(Error::invalid(
                "v0 − f",
                format!("must be finite, got {offset_um}"),
            ));
        }
        let f = self.focal_mm * 1e-3;
        let dv = self.max_shift_m();
        let v0 = f + offset_um * 1e-6;
        let near_img = v0 + dv;
        if near_img <= f {
            return Err(Error::invalid(
                "v0 − f",
                format!(
                    "{offset_um} µm: the sensor is more than Δv_max = {:.2} µm in front of the focal plane, so no object is in focus",
                    dv * 1e6
                ),
            ));
        }
        // Eq. S6: u' = f·v' / (v' − f).
        let object = |v: f64| f * v / (v - f);
        let far_img = v0 - dv;
        Ok(DofRow {
            v0_minus_f_um: offset_um,
            u_near_m: object(near_img),
            u_far_m: (far_img > f).then(|| object(far_img)),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reproduces_table_s1() {
        let p = DofParams::default();
        assert!((p.max_shift_m() - 7.04e-6).abs() < 1e-12);
        let expected = [
            (0.0, 0.37, None),
            (10.0, 0.15, Some(0.87)),
            (15.0, 0.12, Some(0.32)),
            (20.0, 0.10, Some(0.20)),
            (25.0, 0.08, Some(0.14)),
        ];
        for (off, near, far) in expected {
            let r = p.range(off).unwrap();
            assert_eq!(
                (r.u_near_m * 100.0).round() / 100.0,
                near,
                "near at f + {off} µm: {}",
                r.u_near_m
            );
            assert_eq!(
                r.u_far_m.map(|v| (v * 100.0).round() / 100.0),
                far,
                "far at f + {off} µm"
            );
        }
        assert!(p.range(-10.0).is_err());
        assert!(DofParams { pixel_um: 0.0, ..p }.range(0.0).is_err());
    }
}
