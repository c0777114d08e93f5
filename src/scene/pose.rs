//! A layer's pose in a frame: an affine map (sprites, a background's global motion), or the
//! perspective of a plane seen by a camera (a homography: a road under a car's camera), from
//! which the layer's flow is exact.

use serde::{Deserialize, Serialize};

use super::affine::Affine;

/// `p' ~ M·(x, y, 1)` with `M` row-major 3×3, in pixel coordinates (x right, y down). A point
/// is in front of the camera where the third coordinate `w` is positive; the other side of the
/// horizon (`w ≤ 0`) has no image.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Homography {
    pub m: [f64; 9],
}

/// Points with `w` at or below this are at or beyond the horizon.
const MIN_W: f64 = 1e-12;

impl Homography {
    /// The point's image, `None` at or beyond the horizon.
    #[inline]
    pub fn apply(&self, x: f64, y: f64) -> Option<(f64, f64)> {
        let m = &self.m;
        let w = m[6] * x + m[7] * y + m[8];
        (w > MIN_W).then(|| {
            (
                (m[0] * x + m[1] * y + m[2]) / w,
                (m[3] * x + m[4] * y + m[5]) / w,
            )
        })
    }

    /// The third homogeneous coordinate of the point's image (its depth, up to a positive
    /// factor, for a plane's homography).
    #[inline]
    pub fn w(&self, x: f64, y: f64) -> f64 {
        self.m[6] * x + self.m[7] * y + self.m[8]
    }

    /// `self ∘ other`: first `other`, then `self`.
    pub fn compose(&self, other: &Homography) -> Homography {
        let (a, b) = (&self.m, &other.m);
        let mut m = [0.0; 9];
        for r in 0..3 {
            for c in 0..3 {
                m[3 * r + c] = (0..3).map(|k| a[3 * r + k] * b[3 * k + c]).sum();
            }
        }
        Homography { m }
    }

    /// The exact inverse (adjugate over determinant, not rescaled, so that a point in front
    /// maps back with a positive `w`), or `None` for a singular matrix.
    pub fn inverse(&self) -> Option<Homography> {
        let m = &self.m;
        let adj = [
            m[4] * m[8] - m[5] * m[7],
            m[2] * m[7] - m[1] * m[8],
            m[1] * m[5] - m[2] * m[4],
            m[5] * m[6] - m[3] * m[8],
            m[0] * m[8] - m[2] * m[6],
            m[2] * m[3] - m[0] * m[5],
            m[3] * m[7] - m[4] * m[6],
            m[1] * m[6] - m[0] * m[7],
            m[0] * m[4] - m[1] * m[3],
        ];
        let det = m[0] * adj[0] + m[1] * adj[3] + m[2] * adj[6];
        if !det.is_finite() || det.abs() < 1e-12 {
            return None;
        }
        Some(Homography {
            m: adj.map(|v| v / det),
        })
    }
}

impl From<Affine> for Homography {
    fn from(a: Affine) -> Self {
        Homography {
            m: [a.a, a.b, a.tx, a.c, a.d, a.ty, 0.0, 0.0, 1.0],
        }
    }
}

/// A layer's pose: local → image coordinates. Written as the affine map's own fields, or as
/// `{"m": [...]}` for a homography, so that manifests of affine scenes read as before.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Pose {
    Affine(Affine),
    Projective(Homography),
}

impl Pose {
    pub const IDENTITY: Pose = Pose::Affine(Affine::IDENTITY);

    /// The point's image; `None` only for a homography, at or beyond its horizon.
    #[inline]
    pub fn apply(&self, x: f64, y: f64) -> Option<(f64, f64)> {
        match self {
            Pose::Affine(a) => Some(a.apply(x, y)),
            Pose::Projective(h) => h.apply(x, y),
        }
    }

    pub fn inverse(&self) -> Option<Pose> {
        match self {
            Pose::Affine(a) => a.inverse().map(Pose::Affine),
            Pose::Projective(h) => h.inverse().map(Pose::Projective),
        }
    }

    /// How far a local point at distance `r` from the origin can land from the origin's image:
    /// the affine map's Frobenius norm times `r`; unbounded for a homography.
    pub fn reach(&self, r: f64) -> f64 {
        match self {
            Pose::Affine(p) => (p.a * p.a + p.b * p.b + p.c * p.c + p.d * p.d).sqrt() * r,
            Pose::Projective(_) => f64::INFINITY,
        }
    }

    /// Whether every point of the convex hull of `points` (local) is in front of the camera:
    /// `w` is affine in the local coordinates, so its sign on the vertices decides.
    pub fn in_front(&self, points: &[(f64, f64)]) -> bool {
        match self {
            Pose::Affine(_) => true,
            Pose::Projective(h) => points.iter().all(|&(x, y)| h.w(x, y) > MIN_W),
        }
    }
}

impl From<Affine> for Pose {
    fn from(a: Affine) -> Self {
        Pose::Affine(a)
    }
}

impl From<Homography> for Pose {
    fn from(h: Homography) -> Self {
        Pose::Projective(h)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ground() -> Homography {
        // A ground plane (X right, Z ahead, metres) under a camera 1.5 m up: x = 100 + 200 X/Z,
        // y = 50 + 300/Z.
        Homography {
            m: [200.0, 100.0, 0.0, 0.0, 50.0, 300.0, 0.0, 1.0, 0.0],
        }
    }

    #[test]
    fn a_homography_inverts_composes_and_has_a_horizon() {
        let h = ground();
        let (x, y) = h.apply(1.0, 4.0).unwrap();
        assert!((x - 150.0).abs() < 1e-12 && (y - 125.0).abs() < 1e-12);
        let inv = h.inverse().unwrap();
        let (bx, by) = inv.apply(x, y).unwrap();
        assert!((bx - 1.0).abs() < 1e-9 && (by - 4.0).abs() < 1e-9);
        // Above the horizon (y < 50) nothing on the ground is seen; behind the camera neither.
        assert_eq!(inv.apply(120.0, 40.0), None);
        assert_eq!(h.apply(1.0, -2.0), None);
        let id = h.compose(&inv);
        for (k, v) in id.m.iter().enumerate() {
            let want = if k % 4 == 0 { 1.0 } else { 0.0 };
            assert!((v - want).abs() < 1e-9, "{:?}", id.m);
        }
        assert_eq!(Homography { m: [0.0; 9] }.inverse(), None);
    }

    #[test]
    fn an_affine_pose_is_the_same_map_as_its_homography_and_reads_as_before() {
        let a = Affine::pose(10.0, -4.0, 0.3, 1.7);
        let (x, y) = a.apply(3.0, 5.0);
        let (hx, hy) = Homography::from(a).apply(3.0, 5.0).unwrap();
        assert!((x - hx).abs() < 1e-12 && (y - hy).abs() < 1e-12);
        let json = serde_json::to_string(&a).unwrap();
        let p: Pose = serde_json::from_str(&json).unwrap();
        assert_eq!(p, Pose::Affine(a));
        let h: Pose =
            serde_json::from_str(&serde_json::to_string(&Pose::from(ground())).unwrap()).unwrap();
        assert_eq!(h, Pose::Projective(ground()));
        assert!(Pose::from(a).reach(2.0).is_finite() && h.reach(2.0).is_infinite());
        assert!(h.in_front(&[(0.0, 1.0), (3.0, 9.0)]) && !h.in_front(&[(0.0, 1.0), (0.0, -1.0)]));
    }
}
