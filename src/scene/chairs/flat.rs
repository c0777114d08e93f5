//! Flat sprites (`ChairsConfig::flat_sprites`): one flat colour, stretched up to 4:1, with flat
//! marks riding on them: objects whose inside has nothing to match, so that their motion,
//! along their length above all, must be read from their ends and marks (Note S12's rocket).

use std::f64::consts::PI;

use rand::RngExt;

use crate::rng;
use crate::scene::shape::{Shape, blob_boundary};

/// Longest elongation (major over minor axis) of a flat sprite.
const MAX_ELONGATION: f64 = 4.0;
/// Vertices of a flat sprite's outline.
const VERTICES: usize = 64;

/// A flat sprite's outline and marks, in its local frame.
pub(super) struct FlatSprite {
    pub shape: Shape,
    /// Each mark's radius and centre.
    pub marks: Vec<(f64, (f64, f64))>,
}

/// The blob of `radius` and `harmonics` stretched along its local x by an elongation drawn
/// log-uniformly in [1, 4] with its area kept, as a polygon, and 0–2 disc marks of radius
/// 0.15–0.6 of its narrow half-width, each wholly inside it, spread along its length.
pub(super) fn draw(radius: f64, harmonics: &[(u32, f64, f64)], v: &mut rng::Rng) -> FlatSprite {
    let e = v.random_range(0.0..MAX_ELONGATION.ln()).exp();
    let (sx, sy) = (e.sqrt(), 1.0 / e.sqrt());
    let vertices = (0..VERTICES)
        .map(|i| {
            let t = i as f64 * 2.0 * PI / VERTICES as f64;
            let r = blob_boundary(radius, harmonics, t);
            (sx * r * t.cos(), sy * r * t.sin())
        })
        .collect();
    // The blob holds its inner circle, so the stretched outline holds this ellipse (less a
    // margin for the polygon's chords).
    let spread: f64 = harmonics.iter().map(|h| h.1.abs()).sum();
    let inner = 0.97 * radius * (1.0 - spread);
    let (a, b) = (inner * sx, inner * sy);
    let count = v.random_range(0..=2usize);
    let marks = (0..count)
        .map(|_| {
            let m = b * v.random_range(0.15..0.6);
            let mut c = v.random_range(-1.0..=1.0) * (a - m);
            // Halve the offset until the mark's rim is inside the ellipse (c = 0 always is).
            while c != 0.0 && !disc_in_ellipse(c, m, a, b) {
                c = if c.abs() < 1e-6 { 0.0 } else { c / 2.0 };
            }
            (m, (c, 0.0))
        })
        .collect();
    FlatSprite {
        shape: Shape::Polygon { vertices },
        marks,
    }
}

/// Whether the disc of radius `m` at (c, 0) lies inside the ellipse of semi-axes a, b.
fn disc_in_ellipse(c: f64, m: f64, a: f64, b: f64) -> bool {
    (0..64).all(|k| {
        let t = k as f64 * PI / 32.0;
        let (x, y) = (c + m * t.cos(), m * t.sin());
        (x / a).powi(2) + (y / b).powi(2) <= 1.0
    })
}
