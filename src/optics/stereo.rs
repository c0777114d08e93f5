//! Stereo depth with two metalenses (Note S17): the incident angle from the image position by
//! inverting the projection (Eq. S24: x = −f·tan α for a hyperbolic profile, x = −f·sin α for
//! a quadratic one), then Z = Δd / (tan α + tan β) (Eq. S25).

use super::lens::Profile;
use crate::error::{Error, Result};

/// Eq. S24: the incident angle (rad) of a point imaged `x_mm` from the axis.
pub fn incident_angle(profile: Profile, x_mm: f64, focal_mm: f64) -> Result<f64> {
    if !(x_mm.is_finite() && focal_mm.is_finite() && focal_mm > 0.0) {
        return Err(Error::invalid(
            "stereo input",
            format!(
                "image position {x_mm} mm and focal length {focal_mm} mm must be finite, f > 0"
            ),
        ));
    }
    let t = -x_mm / focal_mm;
    match profile {
        Profile::Hyperbolic => Ok(t.atan()),
        Profile::Quadratic => {
            if t.abs() >= 1.0 {
                Err(Error::invalid(
                    "image position",
                    format!(
                        "|x| = {} mm ≥ f = {focal_mm} mm lies beyond the range of the quadratic projection x = −f·sin α",
                        x_mm.abs()
                    ),
                ))
            } else {
                Ok(t.asin())
            }
        }
    }
}

/// Eq. S25: depth (m) of a point imaged at `x1_mm` and `x2_mm` by two lenses `baseline_m` apart.
pub fn depth(
    profile: Profile,
    x1_mm: f64,
    x2_mm: f64,
    focal_mm: f64,
    baseline_m: f64,
) -> Result<f64> {
    if !(baseline_m.is_finite() && baseline_m > 0.0) {
        return Err(Error::invalid(
            "baseline",
            format!("must be finite and > 0, got {baseline_m}"),
        ));
    }
    let (a, b) = (
        incident_angle(profile, x1_mm, focal_mm)?,
        incident_angle(profile, x2_mm, focal_mm)?,
    );
    let s = a.tan() + b.tan();
    if s <= 0.0 {
        return Err(Error::invalid(
            "image positions",
            format!("tan α + tan β = {s:.4} ≤ 0: the two rays do not meet in front of the lenses"),
        ));
    }
    Ok(baseline_m / s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_the_depth_of_a_known_point() {
        // A point 2 m deep, 3 cm from lens 1 and 7 cm from lens 2 (baseline 10 cm).
        let (z, d, f) = (2.0f64, 0.1f64, 1.6f64);
        let (a, b) = ((0.03f64 / z).atan(), (0.07f64 / z).atan());
        for p in [Profile::Hyperbolic, Profile::Quadratic] {
            let proj = |t: f64| match p {
                Profile::Hyperbolic => -f * t.tan(),
                Profile::Quadratic => -f * t.sin(),
            };
            let got = depth(p, proj(a), proj(b), f, d).unwrap();
            assert!((got - z).abs() < 1e-9, "{p:?}: {got}");
        }
        assert!(
            depth(Profile::Hyperbolic, 0.1, 0.1, f, d).is_err(),
            "diverging rays"
        );
        assert!(
            depth(Profile::Quadratic, -1.7, -0.1, f, d).is_err(),
            "beyond f"
        );
    }
}
