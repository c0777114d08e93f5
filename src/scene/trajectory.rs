//! Trajectory scenes (Movies S1–S2, Table S5): textured objects moving along sinusoidal,
//! planar-spiral and smooth random paths at 30 frames per second over a textured still
//! background, with exact flow between consecutive frames and ground-truth centroids.

use std::f64::consts::PI;
use std::sync::Arc;

use rand::RngExt;
use serde::{Deserialize, Serialize};

use super::affine::Affine;
use super::layered::{Fill, Layer, LayeredScene};
use super::shape::Shape;
use super::texture::procedural;
use crate::error::{Error, Result};
use crate::rng;

/// A path family.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PathKind {
    Sinusoid,
    Spiral,
    Random,
}

/// Position at time `t` (seconds) of path `kind` in a `w × h` frame, for path seed `seed`.
pub fn path_position(kind: PathKind, t: f64, w: f64, h: f64, seed: u64) -> (f64, f64) {
    match kind {
        // Left to right across the frame with two periods of vertical oscillation in 4 s.
        PathKind::Sinusoid => (
            0.1 * w + 0.8 * w * (t / 4.0).fract(),
            0.5 * h + 0.25 * h * (2.0 * PI * t / 2.0).sin(),
        ),
        // An outward planar spiral about the centre.
        PathKind::Spiral => {
            let r = 0.05 * h.min(w) + 0.08 * h.min(w) * t;
            let a = 1.5 * t;
            (
                0.5 * w + r.min(0.45 * h.min(w)) * a.cos(),
                0.5 * h + r.min(0.45 * h.min(w)) * a.sin(),
            )
        }
        // A smooth random path: a sum of a few sinusoids with seeded frequencies and phases.
        PathKind::Random => {
            let mut r = rng::stream(seed, &[rng::purpose::SCENE, 77]);
            let (mut x, mut y) = (0.5 * w, 0.5 * h);
            for k in 1..=3 {
                let (fx, fy) = (r.random_range(0.05..0.4), r.random_range(0.05..0.4));
                let (px, py) = (r.random_range(0.0..2.0 * PI), r.random_range(0.0..2.0 * PI));
                x += 0.3 * w / k as f64 * (2.0 * PI * fx * t + px).sin();
                y += 0.3 * h / k as f64 * (2.0 * PI * fy * t + py).sin();
            }
            (x.clamp(0.05 * w, 0.95 * w), y.clamp(0.05 * h, 0.95 * h))
        }
    }
}

/// A trajectory scene: objects on paths, rendered frame by frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrajectoryConfig {
    pub width: usize,
    pub height: usize,
    pub fps: f64,
    pub frames: usize,
    /// One path per object; several objects cross, enter and leave.
    pub paths: Vec<PathKind>,
    /// Object radius in pixels.
    pub radius: f64,
    pub seed: u64,
}

impl Default for TrajectoryConfig {
    fn default() -> Self {
        Self {
            width: 640,
            height: 480,
            fps: 30.0,
            frames: 150,
            paths: vec![PathKind::Sinusoid],
            radius: 16.0,
            seed: 0,
        }
    }
}

impl TrajectoryConfig {
    pub fn validate(&self) -> Result<()> {
        if self.width < 32
            || self.height < 32
            || self.frames < 2
            || self.paths.is_empty()
            || !(self.fps > 0.0 && self.fps.is_finite())
            || !(self.radius > 1.0 && self.radius.is_finite())
        {
            return Err(Error::invalid(
                "trajectory scene",
                "need frames ≥ 2, sides ≥ 32, fps > 0, radius > 1 and at least one path",
            ));
        }
        Ok(())
    }

    /// Ground-truth centroid of object `i` at frame `n`.
    pub fn centroid(&self, i: usize, n: usize) -> (f64, f64) {
        path_position(
            self.paths[i],
            n as f64 / self.fps,
            self.width as f64,
            self.height as f64,
            rng::derive(self.seed, &[i as u64]),
        )
    }

    /// The two-frame scene between frames `n` and `n + 1`.
    pub fn pair(&self, n: usize) -> Result<LayeredScene> {
        self.validate()?;
        let mut r = rng::stream(self.seed, &[rng::purpose::SCENE]);
        let bg = procedural(r.random(), 3, self.height, self.width, self.height as f32);
        let mut layers = vec![Layer {
            shape: Shape::Full,
            fill: Fill::Texture {
                image: Arc::new(bg),
                origin: (0.0, 0.0),
            },
            poses: [Affine::IDENTITY; 2],
        }];
        for i in 0..self.paths.len() {
            let size = (2.0 * self.radius).ceil() as usize + 4;
            let tex = procedural(
                rng::derive(self.seed, &[i as u64, 5]),
                3,
                size,
                size,
                self.radius as f32,
            );
            let (a, b) = (self.centroid(i, n), self.centroid(i, n + 1));
            layers.push(Layer {
                shape: Shape::Disc {
                    radius: self.radius,
                },
                fill: Fill::Texture {
                    image: Arc::new(tex),
                    origin: (size as f64 / 2.0, size as f64 / 2.0),
                },
                poses: [Affine::translation(a.0, a.1), Affine::translation(b.0, b.1)],
            });
        }
        Ok(LayeredScene {
            width: self.width,
            height: self.height,
            channels: 3,
            layers,
            supersample: 2,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flow_moves_the_object_centroid_exactly() {
        let cfg = TrajectoryConfig {
            width: 160,
            height: 120,
            frames: 10,
            paths: vec![PathKind::Spiral, PathKind::Sinusoid],
            radius: 6.0,
            ..TrajectoryConfig::default()
        };
        let scene = cfg.pair(3).unwrap();
        let flow = scene.flow().unwrap();
        let (a, b) = (cfg.centroid(0, 3), cfg.centroid(0, 4));
        let (u, v) = flow.get(a.1.round() as usize, a.0.round() as usize);
        assert!((u as f64 - (b.0 - a.0)).abs() < 1e-4 && (v as f64 - (b.1 - a.1)).abs() < 1e-4);
        assert!(TrajectoryConfig { frames: 1, ..cfg }.validate().is_err());
    }
}
