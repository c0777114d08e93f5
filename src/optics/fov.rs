//! Field of view of the tilted-phase array (Notes S2, S16): the angular sector each lens sees
//! (its tilt ± half its FoV), the total coverage and overlaps, and the focal spot against the
//! Airy radius across a lens's field, from the diffraction PSF.

use serde::Serialize;

use super::diffraction::{PsfParams, spot_radius_um};
use super::lens::Lens;
use crate::error::{Error, Result};

/// The sectors of an array.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Coverage {
    /// Per lens `[from, to]` in degrees, sorted by centre.
    pub sectors: Vec<[f64; 2]>,
    /// Union of the sectors in degrees.
    pub total_deg: f64,
    /// Overlap of each pair of neighbours in degrees (negative: a gap).
    pub overlaps_deg: Vec<f64>,
}

/// Sectors for lenses pointed at `tilts_deg`, each covering `fov_deg`.
pub fn coverage(tilts_deg: &[f64], fov_deg: f64) -> Result<Coverage> {
    if tilts_deg.is_empty() || tilts_deg.iter().any(|t| !t.is_finite() || t.abs() >= 90.0) {
        return Err(Error::invalid(
            "tilts",
            format!("need at least one finite tilt within ±90°, got {tilts_deg:?}"),
        ));
    }
    if !(fov_deg.is_finite() && fov_deg > 0.0 && fov_deg < 180.0) {
        return Err(Error::invalid(
            "fov",
            format!("must be in (0, 180)°, got {fov_deg}"),
        ));
    }
    let mut centres = tilts_deg.to_vec();
    centres.sort_by(|a, b| a.total_cmp(b));
    let sectors: Vec<[f64; 2]> = centres
        .iter()
        .map(|c| [c - fov_deg / 2.0, c + fov_deg / 2.0])
        .collect();
    let overlaps_deg: Vec<f64> = sectors.windows(2).map(|w| w[0][1] - w[1][0]).collect();
    let mut total = 0.0;
    let mut end = f64::NEG_INFINITY;
    for s in &sectors {
        let start = s[0].max(end);
        if s[1] > start {
            total += s[1] - start;
        }
        end = end.max(s[1]);
    }
    Ok(Coverage {
        sectors,
        total_deg: total,
        overlaps_deg,
    })
}

/// The focal spot at one field angle.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SpotRow {
    pub field_angle_deg: f64,
    pub spot_radius_um: f64,
    pub airy_radius_um: f64,
}

/// Spot radius at the design wavelength for `steps + 1` field angles from 0 to half of
/// `fov_deg`, for `lens` (which carries the profile and the tilt), on an FFT grid of `grid`.
pub fn spot_sweep(lens: &Lens, fov_deg: f64, steps: usize, grid: usize) -> Result<Vec<SpotRow>> {
    if steps == 0 || !(fov_deg.is_finite() && fov_deg > 0.0 && fov_deg < 180.0) {
        return Err(Error::invalid(
            "spot sweep",
            format!("need steps > 0 and fov in (0, 180)°, got {steps}, {fov_deg}"),
        ));
    }
    let airy = lens.airy_radius_um(lens.design_wavelength_nm);
    (0..=steps)
        .map(|i| {
            let angle = lens.tilt_deg + fov_deg / 2.0 * i as f64 / steps as f64;
            let params = PsfParams {
                lens: lens.clone(),
                field_angle_deg: angle,
                grid,
                kernel_size: 65,
                ..PsfParams::default()
            };
            Ok(SpotRow {
                field_angle_deg: angle,
                spot_radius_um: spot_radius_um(&params, lens.design_wavelength_nm)?,
                airy_radius_um: airy,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn three_lenses_of_45_degrees_cover_135() {
        let c = coverage(&[-45.0, 0.0, 45.0], 45.0).unwrap();
        assert_eq!(c.total_deg, 135.0);
        assert_eq!(c.overlaps_deg, vec![0.0, 0.0]);
        assert_eq!(c.sectors[0], [-67.5, -22.5]);
        // Concentrated views overlap (more redundancy, less coverage: Note S16).
        let c = coverage(&[-30.0, 0.0, 30.0], 45.0).unwrap();
        assert_eq!(c.total_deg, 105.0);
        assert_eq!(c.overlaps_deg, vec![15.0, 15.0]);
        // Separated views leave gaps.
        let c = coverage(&[-60.0, 0.0, 60.0], 45.0).unwrap();
        assert_eq!(c.total_deg, 135.0);
        assert_eq!(c.overlaps_deg, vec![-15.0, -15.0]);
        assert!(coverage(&[], 45.0).is_err());
        assert!(coverage(&[0.0], 200.0).is_err());
    }
}
