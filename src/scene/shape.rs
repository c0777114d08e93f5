//! Sprite silhouettes in the sprite's own coordinates: smooth star-shaped blobs (the
//! FlyingChairs-like foreground objects), polygons (the Note S12 rocket), discs.

use serde::{Deserialize, Serialize};

/// A region of the plane around the local origin.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Shape {
    /// Covers everything (a background).
    Full,
    /// `|p| ≤ radius`.
    Disc { radius: f64 },
    /// Star-convex blob: `|p| ≤ r(θ) = radius·(1 + Σ_k amp_k cos(k·θ + phase_k))`.
    Blob {
        radius: f64,
        harmonics: Vec<(u32, f64, f64)>,
    },
    /// A simple polygon (even-odd rule), vertices in order.
    Polygon { vertices: Vec<(f64, f64)> },
}

impl Shape {
    /// True if the local point (x, y) is inside.
    pub fn contains(&self, x: f64, y: f64) -> bool {
        match self {
            Shape::Full => true,
            Shape::Disc { radius } => x * x + y * y <= radius * radius,
            Shape::Blob { radius, harmonics } => {
                let r2 = x * x + y * y;
                // r(θ) lies within radius·(1 ± Σ|amp_k|): outside the outer circle nothing is
                // inside, within the inner one everything is, and only the ring between needs θ.
                let spread: f64 = harmonics.iter().map(|h| h.1.abs()).sum();
                let (outer, inner) = (radius * (1.0 + spread), radius * (1.0 - spread));
                if r2 > outer * outer {
                    return false;
                }
                if inner > 0.0 && r2 <= inner * inner {
                    return true;
                }
                let r = blob_boundary(*radius, harmonics, y.atan2(x));
                r2 <= r * r
            }
            Shape::Polygon { vertices } => {
                let mut inside = false;
                let n = vertices.len();
                for i in 0..n {
                    let (x1, y1) = vertices[i];
                    let (x2, y2) = vertices[(i + 1) % n];
                    if (y1 > y) != (y2 > y) && x < x1 + (y - y1) * (x2 - x1) / (y2 - y1) {
                        inside = !inside;
                    }
                }
                inside
            }
        }
    }

    /// A radius around the local origin outside which nothing is inside (∞ for `Full`).
    pub fn bound_radius(&self) -> f64 {
        match self {
            Shape::Full => f64::INFINITY,
            Shape::Disc { radius } => *radius,
            Shape::Blob { radius, harmonics } => {
                radius * (1.0 + harmonics.iter().map(|h| h.1.abs()).sum::<f64>())
            }
            Shape::Polygon { vertices } => vertices
                .iter()
                .map(|(x, y)| (x * x + y * y).sqrt())
                .fold(0.0, f64::max),
        }
    }
}

/// A blob's boundary r(θ) = radius·(1 + Σ_k amp_k cos(k·θ + phase_k)).
pub(crate) fn blob_boundary(radius: f64, harmonics: &[(u32, f64, f64)], theta: f64) -> f64 {
    radius
        * (1.0
            + harmonics
                .iter()
                .map(|&(k, a, p)| a * (k as f64 * theta + p).cos())
                .sum::<f64>())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn containment() {
        assert!(Shape::Disc { radius: 2.0 }.contains(1.0, 1.0));
        assert!(!Shape::Disc { radius: 1.0 }.contains(1.0, 1.0));
        let square = Shape::Polygon {
            vertices: vec![(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)],
        };
        assert!(square.contains(0.5, -0.5));
        assert!(!square.contains(1.5, 0.0));
        let blob = Shape::Blob {
            radius: 10.0,
            harmonics: vec![(3, 0.3, 0.0)],
        };
        assert!(blob.contains(12.0, 0.0)); // r(0) = 13
        assert!(!blob.contains(-12.0, 0.0)); // r(π) = 7
        assert!((blob.bound_radius() - 13.0).abs() < 1e-12);
    }

    /// The inner and outer circles decide only what the star-shaped boundary would: on a grid
    /// of points around blobs of several spreads (one above 1, where no inner circle exists),
    /// `contains` agrees with r(θ) evaluated at every point.
    #[test]
    fn blob_shortcuts_agree_with_the_boundary() {
        for harmonics in [
            vec![(3, 0.3, 0.0)],
            vec![(2, 0.25, 1.0), (5, 0.1, -0.4)],
            vec![(1, 0.7, 0.3), (4, 0.6, 2.0)],
        ] {
            let radius = 9.0;
            let blob = Shape::Blob {
                radius,
                harmonics: harmonics.clone(),
            };
            for i in -90..=90 {
                for j in -90..=90 {
                    let (x, y) = (i as f64 * 0.23, j as f64 * 0.19);
                    let r = blob_boundary(radius, &harmonics, y.atan2(x));
                    assert_eq!(blob.contains(x, y), x * x + y * y <= r * r, "({x}, {y})");
                }
            }
        }
    }
}
