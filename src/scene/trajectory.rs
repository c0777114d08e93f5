//! Trajectory scenes (Movies S1–S2, Table S5): textured discs moving along sinusoidal,
//! planar-spiral, smooth random and straight paths at 30 frames per second over a textured
//! still background, with exact flow between consecutive frames and ground-truth centroids.
//! Objects may start or end outside the frame (entering and leaving) and cross each other.

use std::f64::consts::PI;
use std::sync::Arc;

use rand::RngExt;
use serde::{Deserialize, Serialize};

use super::affine::Affine;
use super::layered::{Fill, Layer, LayeredScene};
use super::pose::Pose;
use super::shape::Shape;
use super::texture::procedural;
use crate::error::{Error, Result};
use crate::rng;
use crate::types::{Flow, Image};

/// A path family.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PathKind {
    /// Left to right at 0.16 frame widths per second, oscillating vertically by ±0.2 frame
    /// heights with a period of 4 s.
    Sinusoid,
    /// An outward planar spiral about the frame centre.
    Spiral,
    /// A smooth random path: three seeded sinusoids per axis.
    Random,
    /// A straight line from `from` to `to` over the clip (frame fractions; may lie outside).
    Line,
}

/// One moving object.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ObjectSpec {
    pub path: PathKind,
    /// Disc radius in pixels.
    pub radius: f64,
    /// Line end points as fractions of the frame width and height.
    pub from: [f64; 2],
    pub to: [f64; 2],
    /// Time offset into the path (s) and time scale: the object is at path time
    /// `start + rate · n / fps` in frame n.
    pub start: f64,
    pub rate: f64,
}

impl Default for ObjectSpec {
    fn default() -> Self {
        Self {
            path: PathKind::Sinusoid,
            radius: 16.0,
            from: [-0.1, 0.5],
            to: [1.1, 0.5],
            start: 0.0,
            rate: 1.0,
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
    /// Objects, drawn bottom to top (a later object occludes an earlier one where they cross).
    pub objects: Vec<ObjectSpec>,
    pub seed: u64,
}

impl Default for TrajectoryConfig {
    fn default() -> Self {
        Self {
            width: 640,
            height: 480,
            fps: 30.0,
            frames: 150,
            objects: vec![ObjectSpec::default()],
            seed: 0,
        }
    }
}

impl TrajectoryConfig {
    pub fn validate(&self) -> Result<()> {
        if self.width < 32 || self.height < 32 || self.width > 8192 || self.height > 8192 {
            return Err(Error::invalid(
                "scene",
                format!(
                    "frame sides must be 32..=8192, got {}x{}",
                    self.width, self.height
                ),
            ));
        }
        if self.frames < 2 || self.frames > 100_000 {
            return Err(Error::invalid(
                "scene.frames",
                format!("must be 2..=100000, got {}", self.frames),
            ));
        }
        if !(self.fps > 0.0 && self.fps.is_finite()) {
            return Err(Error::invalid(
                "scene.fps",
                format!("must be finite and > 0, got {}", self.fps),
            ));
        }
        if self.objects.is_empty() {
            return Err(Error::invalid("scene.objects", "needs at least one object"));
        }
        for (i, o) in self.objects.iter().enumerate() {
            let finite = o.from.iter().chain(&o.to).all(|v| v.is_finite())
                && o.start.is_finite()
                && o.rate.is_finite();
            if !(o.radius > 1.0 && o.radius.is_finite() && finite) {
                return Err(Error::invalid(
                    format!("scene.objects[{i}]"),
                    "radius must be > 1 and every number finite",
                ));
            }
            if 2.0 * o.radius >= self.width.min(self.height) as f64 {
                return Err(Error::invalid(
                    format!("scene.objects[{i}].radius"),
                    format!(
                        "{} does not fit a {}x{} frame",
                        o.radius, self.width, self.height
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Path time (s) of object `i` in frame `n`.
    fn time(&self, i: usize, n: usize) -> f64 {
        let o = &self.objects[i];
        o.start + o.rate * n as f64 / self.fps
    }

    /// Ground-truth centre of object `i` at frame `n` (it may lie outside the frame).
    pub fn centroid(&self, i: usize, n: usize) -> (f64, f64) {
        let o = &self.objects[i];
        let (w, h) = (self.width as f64, self.height as f64);
        let t = self.time(i, n);
        match o.path {
            PathKind::Sinusoid => (
                0.1 * w + 0.16 * w * t,
                0.5 * h + 0.2 * h * (0.5 * PI * t).sin(),
            ),
            PathKind::Spiral => {
                let m = h.min(w);
                let r = (0.05 * m + 0.08 * m * t).min(0.4 * m);
                let a = 1.5 * t;
                (0.5 * w + r * a.cos(), 0.5 * h + r * a.sin())
            }
            PathKind::Random => {
                let mut r = rng::stream(
                    rng::derive(self.seed, &[i as u64]),
                    &[rng::purpose::SCENE, 77],
                );
                let (mut x, mut y) = (0.5 * w, 0.5 * h);
                for k in 1..=3 {
                    let (fx, fy) = (r.random_range(0.05..0.4), r.random_range(0.05..0.4));
                    let (px, py) = (r.random_range(0.0..2.0 * PI), r.random_range(0.0..2.0 * PI));
                    x += 0.3 * w / k as f64 * (2.0 * PI * fx * t + px).sin();
                    y += 0.3 * h / k as f64 * (2.0 * PI * fy * t + py).sin();
                }
                (x.clamp(0.05 * w, 0.95 * w), y.clamp(0.05 * h, 0.95 * h))
            }
            PathKind::Line => {
                let u = t * self.fps / (self.frames - 1) as f64;
                (
                    w * (o.from[0] + (o.to[0] - o.from[0]) * u),
                    h * (o.from[1] + (o.to[1] - o.from[1]) * u),
                )
            }
        }
    }

    /// True when object `i` lies wholly inside frame `n`.
    pub fn visible(&self, i: usize, n: usize) -> bool {
        let (x, y) = self.centroid(i, n);
        let r = self.objects[i].radius;
        x - r >= 0.0
            && y - r >= 0.0
            && x + r <= (self.width - 1) as f64
            && y + r <= (self.height - 1) as f64
    }

    /// The two-frame scene between frames `n` and `n + 1`.
    pub fn pair(&self, n: usize) -> Result<LayeredScene> {
        self.pair_between(n, n + 1)
    }

    /// The two-frame scene between frames `a` and `b` (frames a stream processed at uneven
    /// gaps pairs).
    pub fn pair_between(&self, a: usize, b: usize) -> Result<LayeredScene> {
        self.validate()?;
        let mut r = rng::stream(self.seed, &[rng::purpose::SCENE]);
        let bg = procedural(r.random(), 3, self.height, self.width, self.height as f32);
        let mut layers = vec![Layer {
            shape: Shape::Full,
            fill: Fill::Texture {
                image: Arc::new(bg),
                origin: (0.0, 0.0),
            },
            poses: [Pose::IDENTITY; 2],
        }];
        for (i, o) in self.objects.iter().enumerate() {
            let size = (2.0 * o.radius).ceil() as usize + 4;
            let tex = procedural(
                rng::derive(self.seed, &[i as u64, 5]),
                3,
                size,
                size,
                o.radius as f32,
            );
            let (from, to) = (self.centroid(i, a), self.centroid(i, b));
            layers.push(Layer {
                shape: Shape::Disc { radius: o.radius },
                fill: Fill::Texture {
                    image: Arc::new(tex),
                    origin: (size as f64 / 2.0, size as f64 / 2.0),
                },
                poses: [
                    Affine::translation(from.0, from.1).into(),
                    Affine::translation(to.0, to.1).into(),
                ],
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

    /// Frame `n` as linear intensity `[3, H, W]`.
    pub fn frame(&self, n: usize) -> Result<Image> {
        self.check_frame(n, self.frames)?;
        if n + 1 < self.frames {
            self.pair(n)?.render(0)
        } else {
            self.pair(n - 1)?.render(1)
        }
    }

    /// Exact flow from frame `n` to frame `n + 1`.
    pub fn flow(&self, n: usize) -> Result<Flow> {
        self.check_frame(n, self.frames - 1)?;
        self.pair(n)?.flow()
    }

    /// Exact flow from frame `a` to frame `b`.
    pub fn flow_between(&self, a: usize, b: usize) -> Result<Flow> {
        self.check_frame(a, self.frames)?;
        self.check_frame(b, self.frames)?;
        self.pair_between(a, b)?.flow()
    }

    fn check_frame(&self, n: usize, end: usize) -> Result<()> {
        if n >= end {
            return Err(Error::invalid(
                "frame",
                format!(
                    "{n} is past the clip's last index {}",
                    end.saturating_sub(1)
                ),
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two_objects() -> TrajectoryConfig {
        TrajectoryConfig {
            width: 160,
            height: 120,
            frames: 10,
            objects: vec![
                ObjectSpec {
                    path: PathKind::Spiral,
                    radius: 6.0,
                    ..ObjectSpec::default()
                },
                ObjectSpec {
                    path: PathKind::Line,
                    radius: 6.0,
                    ..ObjectSpec::default()
                },
            ],
            ..TrajectoryConfig::default()
        }
    }

    #[test]
    fn flow_moves_the_object_centroid_exactly() {
        let cfg = two_objects();
        let flow = cfg.flow(3).unwrap();
        let (a, b) = (cfg.centroid(0, 3), cfg.centroid(0, 4));
        let (u, v) = flow.get(a.1.round() as usize, a.0.round() as usize);
        assert!((u as f64 - (b.0 - a.0)).abs() < 1e-4 && (v as f64 - (b.1 - a.1)).abs() < 1e-4);
        assert!(
            TrajectoryConfig {
                frames: 1,
                ..cfg.clone()
            }
            .validate()
            .is_err()
        );
        assert!(cfg.flow(9).is_err() && cfg.frame(9).is_ok() && cfg.frame(10).is_err());
    }

    #[test]
    fn a_line_enters_and_leaves_the_frame() {
        let cfg = two_objects();
        // From 10 % left of the frame to 10 % right of it over the clip.
        assert!(!cfg.visible(1, 0) && cfg.visible(1, 5) && !cfg.visible(1, 9));
        let (x0, _) = cfg.centroid(1, 0);
        let (x9, _) = cfg.centroid(1, 9);
        assert!((x0 + 16.0).abs() < 1e-9 && (x9 - 176.0).abs() < 1e-9);
        // Paths are continuous: no jump between consecutive frames of a long clip.
        let long = TrajectoryConfig {
            frames: 300,
            ..TrajectoryConfig::default()
        };
        for n in 0..299 {
            let (a, b) = (long.centroid(0, n), long.centroid(0, n + 1));
            assert!((a.0 - b.0).hypot(a.1 - b.1) < 20.0, "jump at frame {n}");
        }
    }
}
