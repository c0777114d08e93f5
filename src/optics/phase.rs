//! Note S2, Fig. S2b: metalens phase profiles (hyperbolic, quadratic) and the linear tilt term k·x·sin θt.

use super::lens::Profile;
use std::f64::consts::PI;

/// Design phase in radians at radius `r_m` (metres) for a lens of focal length `f_m` designed at
/// `lambda_design_m`:
/// hyperbolic φ(r) = −(2π/λ)(√(r²+f²) − f), quadratic φ(r) = −π r²/(λ f).
/// Both are 0 on the axis and agree to second order in r/f.
pub fn phase(profile: Profile, r_m: f64, lambda_design_m: f64, f_m: f64) -> f64 {
    match profile {
        Profile::Hyperbolic => {
            // √(r²+f²) − f written as r²/(√(r²+f²) + f) to avoid cancellation near the axis.
            let sag = r_m * r_m / ((r_m * r_m + f_m * f_m).sqrt() + f_m);
            -2.0 * PI / lambda_design_m * sag
        }
        Profile::Quadratic => -PI * r_m * r_m / (lambda_design_m * f_m),
    }
}

/// Radial slope dφ/dr of [`phase`] in radians per metre (negative: the lens converges light).
pub fn phase_slope(profile: Profile, r_m: f64, lambda_design_m: f64, f_m: f64) -> f64 {
    match profile {
        Profile::Hyperbolic => -2.0 * PI / lambda_design_m * r_m / (r_m * r_m + f_m * f_m).sqrt(),
        Profile::Quadratic => -2.0 * PI * r_m / (lambda_design_m * f_m),
    }
}

/// Linear tilt phase k·x·sin θt (k = 2π/λ_design) at position `x_m` for tilt `tilt_rad`.
///
/// Convention: a source at field angle θ (lying toward +x) sends the plane wave exp(−i k x sin θ)
/// onto the lens, so the tilt term cancels it at θ = θt: a positive tilt moves the viewing
/// direction toward +x field angles (and its image toward −x on the sensor).
pub fn tilt_phase(x_m: f64, lambda_design_m: f64, tilt_rad: f64) -> f64 {
    2.0 * PI / lambda_design_m * x_m * tilt_rad.sin()
}

#[cfg(test)]
mod tests {
    use super::*;

    const L: f64 = 532e-9;
    const F: f64 = 1.6e-3;

    #[test]
    fn profiles_agree_near_axis() {
        for r in [1e-6, 1e-5, 5e-5] {
            let h = phase(Profile::Hyperbolic, r, L, F);
            let q = phase(Profile::Quadratic, r, L, F);
            // Difference is k r⁴/(8 f³): relative error (r/f)²/4.
            assert!(((h - q) / q).abs() < (r / F).powi(2), "r={r}: {h} vs {q}");
        }
        assert_eq!(phase(Profile::Hyperbolic, 0.0, L, F), 0.0);
        // At the paper lens edge (r = 0.5 mm) they differ by several waves.
        let d = phase(Profile::Hyperbolic, 0.5e-3, L, F) - phase(Profile::Quadratic, 0.5e-3, L, F);
        assert!(d / (2.0 * PI) > 3.0, "{d}");
    }

    #[test]
    fn edge_gradient_gives_marginal_ray_angle() {
        let (r, h) = (0.5e-3, 1e-9);
        let k = 2.0 * PI / L;
        let g = (phase(Profile::Hyperbolic, r + h, L, F) - phase(Profile::Hyperbolic, r - h, L, F))
            / (2.0 * h);
        // The hyperbolic lens bends the marginal ray toward the focus: sin u = r/√(r²+f²).
        let sin_u = -g / k;
        assert!((g - phase_slope(Profile::Hyperbolic, r, L, F)).abs() < 1e-3 * g.abs());
        assert!((sin_u - r / (r * r + F * F).sqrt()).abs() < 1e-6, "{sin_u}");
        let gq = (phase(Profile::Quadratic, r + h, L, F) - phase(Profile::Quadratic, r - h, L, F))
            / (2.0 * h);
        assert!((-gq / k - r / F).abs() < 1e-6);
    }

    #[test]
    fn tilt_sign_and_size() {
        let t = 45f64.to_radians();
        let k = 2.0 * PI / L;
        assert!((tilt_phase(1e-4, L, t) - k * 1e-4 * t.sin()).abs() < 1e-9);
        // Cancels the incident wave exp(−i k x sin θ) of a source at θ = +θt.
        assert!((tilt_phase(3e-4, L, t) - k * 3e-4 * t.sin()).abs() < 1e-6);
        assert!(tilt_phase(1e-4, L, -t) < 0.0);
    }
}
