//! The lens mapping of a tilted metalens (Notes S2, S17, Eq. S24), derived from the physics: a
//! scene direction with direction cosines (αx, αy) reaches a lens whose linear phase k·x·sin θt
//! shifts it to αx' = αx − sin θt; the lens then images it at r = f·tan θ' (hyperbolic profile)
//! or r = f·sin θ' (quadratic), θ' the angle of the shifted direction from the axis. Images are
//! stored upright (the 180° inversion of a real lens is a fixed flip the calibration absorbs).

use crate::optics::Profile;

/// Direction cosines of the scene direction at horizontal angle `h` and vertical angle `v`
/// (radians), on the "latitude/longitude" grid of the stitched image.
#[inline]
pub fn direction(h: f64, v: f64) -> (f64, f64) {
    (v.cos() * h.sin(), v.sin())
}

/// Scene angles `(h, v)` of direction cosines `(ax, ay)` in the forward hemisphere.
#[inline]
pub fn angles(ax: f64, ay: f64) -> Option<(f64, f64)> {
    let g2 = 1.0 - ax * ax - ay * ay;
    if g2.is_nan() || g2 <= 0.0 {
        return None;
    }
    Some((ax.atan2(g2.sqrt()), ay.asin()))
}

/// Sensor offset (pixels from the axis) of a direction for a lens tilted by `tilt` (radians).
pub fn project(profile: Profile, focal_px: f64, tilt: f64, ax: f64, ay: f64) -> Option<(f64, f64)> {
    let axp = ax - tilt.sin();
    let s2 = axp * axp + ay * ay;
    if s2 >= 1.0 {
        return None;
    }
    match profile {
        Profile::Hyperbolic => {
            let g = (1.0 - s2).sqrt();
            Some((focal_px * axp / g, focal_px * ay / g))
        }
        Profile::Quadratic => Some((focal_px * axp, focal_px * ay)),
    }
}

/// Inverse of [`project`]: the direction cosines seen at sensor offset `(x, y)`.
pub fn unproject(profile: Profile, focal_px: f64, tilt: f64, x: f64, y: f64) -> Option<(f64, f64)> {
    let (axp, ay) = match profile {
        Profile::Hyperbolic => {
            let g = 1.0 / (1.0 + (x * x + y * y) / (focal_px * focal_px)).sqrt();
            (x / focal_px * g, y / focal_px * g)
        }
        Profile::Quadratic => {
            let (a, b) = (x / focal_px, y / focal_px);
            if a * a + b * b >= 1.0 {
                return None;
            }
            (a, b)
        }
    };
    let ax = axp + tilt.sin();
    (ax * ax + ay * ay < 1.0).then_some((ax, ay))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_and_asymmetry() {
        let f = 727.0;
        for profile in [Profile::Hyperbolic, Profile::Quadratic] {
            for tilt in [-45f64, 0.0, 45.0] {
                let t = tilt.to_radians();
                for (h, v) in [(t + 0.3, 0.2), (t - 0.35, -0.3), (t, 0.0)] {
                    let (ax, ay) = direction(h, v);
                    let (x, y) = project(profile, f, t, ax, ay).unwrap();
                    let (bx, by) = unproject(profile, f, t, x, y).unwrap();
                    let (h2, v2) = angles(bx, by).unwrap();
                    assert!(
                        (h2 - h).abs() < 1e-9 && (v2 - v).abs() < 1e-9,
                        "{profile:?} {tilt}"
                    );
                }
            }
        }
        // The centre lens is symmetric; a side lens compresses its outer half (Note S3).
        let c = |h: f64, t: f64| {
            project(Profile::Hyperbolic, f, t, direction(h, 0.0).0, 0.0)
                .unwrap()
                .0
        };
        let q = 22.5f64.to_radians();
        assert!((c(q, 0.0) + c(-q, 0.0)).abs() < 1e-9);
        let t = 45f64.to_radians();
        let (outer, inner) = (c(t + q, t).abs(), c(t - q, t).abs());
        assert!(outer < 0.8 * inner, "outer {outer} inner {inner}");
    }
}
