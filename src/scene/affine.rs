//! 2-D affine transforms: a layer's pose in each frame, from which its flow is exact.

use serde::{Deserialize, Serialize};

/// `p' = A·p + t` with `A = [[a, b], [c, d]]`, in pixel coordinates (x right, y down).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Affine {
    pub a: f64,
    pub b: f64,
    pub c: f64,
    pub d: f64,
    pub tx: f64,
    pub ty: f64,
}

impl Affine {
    pub const IDENTITY: Affine = Affine {
        a: 1.0,
        b: 0.0,
        c: 0.0,
        d: 1.0,
        tx: 0.0,
        ty: 0.0,
    };

    /// Translation by (tx, ty).
    pub fn translation(tx: f64, ty: f64) -> Self {
        Self {
            tx,
            ty,
            ..Self::IDENTITY
        }
    }

    /// A pose: scale `s`, then rotate by `theta` (radians, clockwise on screen since y points
    /// down), then move the origin to `(x, y)`.
    pub fn pose(x: f64, y: f64, theta: f64, s: f64) -> Self {
        let (sn, cs) = theta.sin_cos();
        Self {
            a: s * cs,
            b: -s * sn,
            c: s * sn,
            d: s * cs,
            tx: x,
            ty: y,
        }
    }

    /// Applies the transform to a point.
    #[inline]
    pub fn apply(&self, x: f64, y: f64) -> (f64, f64) {
        (
            self.a * x + self.b * y + self.tx,
            self.c * x + self.d * y + self.ty,
        )
    }

    /// `self ∘ other`: first `other`, then `self`.
    pub fn compose(&self, other: &Affine) -> Affine {
        Affine {
            a: self.a * other.a + self.b * other.c,
            b: self.a * other.b + self.b * other.d,
            c: self.c * other.a + self.d * other.c,
            d: self.c * other.b + self.d * other.d,
            tx: self.a * other.tx + self.b * other.ty + self.tx,
            ty: self.c * other.tx + self.d * other.ty + self.ty,
        }
    }

    /// The inverse, or `None` for a singular (zero-area) transform.
    pub fn inverse(&self) -> Option<Affine> {
        let det = self.a * self.d - self.b * self.c;
        if det.abs() < 1e-12 || !det.is_finite() {
            return None;
        }
        let (a, b, c, d) = (self.d / det, -self.b / det, -self.c / det, self.a / det);
        Some(Affine {
            a,
            b,
            c,
            d,
            tx: -(a * self.tx + b * self.ty),
            ty: -(c * self.tx + d * self.ty),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse_and_compose() {
        let t = Affine::pose(10.0, -4.0, 0.3, 1.7);
        let inv = t.inverse().unwrap();
        let (x, y) = t.apply(3.0, 5.0);
        let (bx, by) = inv.apply(x, y);
        assert!((bx - 3.0).abs() < 1e-12 && (by - 5.0).abs() < 1e-12);
        let id = t.compose(&inv);
        assert!((id.a - 1.0).abs() < 1e-12 && id.b.abs() < 1e-12 && id.tx.abs() < 1e-12);
        assert!(
            Affine {
                a: 0.0,
                d: 0.0,
                ..Affine::IDENTITY
            }
            .inverse()
            .is_none()
        );
    }

    #[test]
    fn rotation_is_clockwise_on_screen() {
        let (x, y) = Affine::pose(0.0, 0.0, std::f64::consts::FRAC_PI_2, 1.0).apply(1.0, 0.0);
        assert!(x.abs() < 1e-12 && (y - 1.0).abs() < 1e-12);
    }
}
