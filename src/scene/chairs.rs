//! FlyingChairs-like procedural scenes: a textured background under a small global affine
//! motion and textured blob sprites under independent translations, rotations and scalings.

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

/// How chairs scenes are drawn. Ranges are `[min, max]`; every default is here.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ChairsConfig {
    pub width: usize,
    pub height: usize,
    /// 3 for colour, 1 for a grey scene (convolved and stored as one channel).
    pub channels: usize,
    /// Number of sprites.
    pub sprites: [usize; 2],
    /// Sprite radius as a fraction of the shorter frame side.
    pub sprite_radius: [f64; 2],
    /// Largest sprite translation between the frames, pixels.
    pub max_translation: f64,
    /// Largest sprite rotation between the frames, degrees.
    pub max_rotation_deg: f64,
    /// Range of the sprite scale factor between the frames.
    pub scale_change: [f64; 2],
    /// Largest background translation, pixels.
    pub background_translation: f64,
    /// Largest background rotation, degrees.
    pub background_rotation_deg: f64,
    /// Range of the background zoom between the frames.
    pub background_zoom: [f64; 2],
    /// Sub-samples per pixel side (anti-aliasing).
    pub supersample: usize,
}

impl Default for ChairsConfig {
    fn default() -> Self {
        Self {
            width: 512,
            height: 384,
            channels: 3,
            sprites: [3, 8],
            sprite_radius: [0.06, 0.22],
            max_translation: 24.0,
            max_rotation_deg: 12.0,
            scale_change: [0.93, 1.07],
            background_translation: 8.0,
            background_rotation_deg: 2.0,
            background_zoom: [0.97, 1.03],
            supersample: 3,
        }
    }
}

fn check_range(name: &str, r: [f64; 2], lo: f64, hi: f64) -> Result<()> {
    if !(r[0].is_finite() && r[1].is_finite() && lo <= r[0] && r[0] <= r[1] && r[1] <= hi) {
        return Err(Error::invalid(
            name,
            format!("expected {lo} <= min <= max <= {hi}, got {r:?}"),
        ));
    }
    Ok(())
}

impl ChairsConfig {
    /// Checks every field, naming the first bad one.
    pub fn validate(&self) -> Result<()> {
        if self.width < 8 || self.height < 8 || self.width > 16384 || self.height > 16384 {
            return Err(Error::invalid(
                "scene size",
                format!(
                    "{}x{}: each side must be 8..=16384",
                    self.width, self.height
                ),
            ));
        }
        if self.channels != 1 && self.channels != 3 {
            return Err(Error::invalid(
                "scene.channels",
                format!("must be 1 or 3, got {}", self.channels),
            ));
        }
        if self.sprites[0] > self.sprites[1] || self.sprites[1] > 256 {
            return Err(Error::invalid(
                "scene.sprites",
                format!("expected min <= max <= 256, got {:?}", self.sprites),
            ));
        }
        check_range("scene.sprite_radius", self.sprite_radius, 0.005, 2.0)?;
        check_range("scene.scale_change", self.scale_change, 0.1, 10.0)?;
        check_range("scene.background_zoom", self.background_zoom, 0.1, 10.0)?;
        for (name, v) in [
            ("scene.max_translation", self.max_translation),
            ("scene.max_rotation_deg", self.max_rotation_deg),
            ("scene.background_translation", self.background_translation),
            (
                "scene.background_rotation_deg",
                self.background_rotation_deg,
            ),
        ] {
            if !v.is_finite() || v < 0.0 {
                return Err(Error::invalid(
                    name,
                    format!("must be finite and >= 0, got {v}"),
                ));
            }
        }
        if self.supersample == 0 || self.supersample > 8 {
            return Err(Error::invalid(
                "scene.supersample",
                format!("must be 1..=8, got {}", self.supersample),
            ));
        }
        Ok(())
    }

    /// Draws the scene for `seed` (a sample's own seed).
    pub fn build(&self, seed: u64) -> Result<LayeredScene> {
        self.validate()?;
        let mut r = rng::stream(seed, &[rng::purpose::SCENE]);
        let (w, h) = (self.width as f64, self.height as f64);
        let short = w.min(h);
        let mut layers = Vec::new();

        // Background: a texture a quarter larger than the frame, moved about the frame centre.
        let (tw, th) = ((w * 1.25).ceil() as usize, (h * 1.25).ceil() as usize);
        let bg_tex = procedural(r.random(), self.channels, th, tw, short as f32);
        let pose1 = Affine::translation(w / 2.0, h / 2.0);
        let centre_motion = {
            let (dx, dy) = disc_sample(&mut r, self.background_translation);
            let theta = r.random_range(-1.0..=1.0) * self.background_rotation_deg.to_radians();
            let zoom = uniform(&mut r, self.background_zoom);
            Affine::translation(w / 2.0 + dx, h / 2.0 + dy)
                .compose(&Affine::pose(0.0, 0.0, theta, zoom))
                .compose(&Affine::translation(-w / 2.0, -h / 2.0))
        };
        layers.push(Layer {
            shape: Shape::Full,
            fill: Fill::Texture {
                image: Arc::new(bg_tex),
                origin: (tw as f64 / 2.0, th as f64 / 2.0),
            },
            poses: [pose1, centre_motion.compose(&pose1)],
        });

        let count = r.random_range(self.sprites[0]..=self.sprites[1]);
        for _ in 0..count {
            let radius = uniform(&mut r, self.sprite_radius) * short;
            let harmonics: Vec<(u32, f64, f64)> = (2..=5)
                .map(|k| {
                    (
                        k,
                        r.random_range(0.0..0.25) / (k as f64 - 1.0),
                        r.random_range(0.0..2.0 * PI),
                    )
                })
                .collect();
            let shape = Shape::Blob { radius, harmonics };
            let bound = shape.bound_radius();
            let size = (2.0 * bound * 1.3).ceil().max(4.0) as usize + 2;
            let tex = procedural(r.random(), self.channels, size, size, (2.0 * radius) as f32);
            let (x, y) = (r.random_range(-0.1..1.1) * w, r.random_range(-0.1..1.1) * h);
            let (theta, s) = (r.random_range(0.0..2.0 * PI), r.random_range(0.85..1.15));
            let (dx, dy) = disc_sample(&mut r, self.max_translation);
            let dtheta = r.random_range(-1.0..=1.0) * self.max_rotation_deg.to_radians();
            let ds = uniform(&mut r, self.scale_change);
            layers.push(Layer {
                shape,
                fill: Fill::Texture {
                    image: Arc::new(tex),
                    origin: (size as f64 / 2.0, size as f64 / 2.0),
                },
                poses: [
                    Affine::pose(x, y, theta, s),
                    Affine::pose(x + dx, y + dy, theta + dtheta, s * ds),
                ],
            });
        }
        Ok(LayeredScene {
            width: self.width,
            height: self.height,
            channels: self.channels,
            layers,
            supersample: self.supersample,
        })
    }
}

fn uniform(r: &mut rng::Rng, range: [f64; 2]) -> f64 {
    if range[0] == range[1] {
        range[0]
    } else {
        r.random_range(range[0]..=range[1])
    }
}

/// A point uniform in the disc of radius `max`.
fn disc_sample(r: &mut rng::Rng, max: f64) -> (f64, f64) {
    let rad = max * r.random::<f64>().sqrt();
    let phi = r.random_range(0.0..2.0 * PI);
    (rad * phi.cos(), rad * phi.sin())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small() -> ChairsConfig {
        ChairsConfig {
            width: 64,
            height: 48,
            supersample: 2,
            ..ChairsConfig::default()
        }
    }

    #[test]
    fn scenes_are_deterministic_and_move() {
        let cfg = small();
        let a = cfg.build(5).unwrap();
        let b = cfg.build(5).unwrap();
        assert_eq!(a.render(0).unwrap(), b.render(0).unwrap());
        assert_eq!(a.flow().unwrap(), b.flow().unwrap());
        assert_ne!(
            a.render(0).unwrap(),
            cfg.build(6).unwrap().render(0).unwrap()
        );
        assert!(!a.is_static());
        let f = a.flow().unwrap();
        assert!(f.max_magnitude() > 0.0 && f.max_magnitude() < 80.0);
    }

    #[test]
    fn warping_frame2_by_the_flow_reproduces_frame1() {
        // Brightness constancy on non-occluded pixels: the exactness of the flow.
        let cfg = ChairsConfig {
            supersample: 1,
            sprites: [2, 2],
            ..small()
        };
        let scene = cfg.build(3).unwrap();
        let (f1, f2, flow) = (
            scene.render(0).unwrap(),
            scene.render(1).unwrap(),
            scene.flow().unwrap(),
        );
        let (mut err_flow, mut err_zero, mut n) = (0.0f64, 0.0f64, 0);
        for y in 4..44 {
            for x in 4..60 {
                let (u, v) = flow.get(y, x);
                let (x2, y2) = (x as f32 + u, y as f32 + v);
                if x2 < 0.0 || y2 < 0.0 || x2 > 63.0 || y2 > 47.0 {
                    continue;
                }
                let warped = super::super::texture::sample_bilinear(&f2, 1, x2, y2);
                err_flow += (warped - f1.get(1, y, x)).abs() as f64;
                err_zero += (f2.get(1, y, x) - f1.get(1, y, x)).abs() as f64;
                n += 1;
            }
        }
        assert!(n > 1000);
        assert!(
            err_flow < 0.5 * err_zero,
            "warp {err_flow} vs zero-flow {err_zero}"
        );
    }

    #[test]
    fn bad_config_is_rejected() {
        assert!(
            ChairsConfig {
                sprites: [5, 2],
                ..small()
            }
            .validate()
            .is_err()
        );
        assert!(
            ChairsConfig {
                max_translation: f64::NAN,
                ..small()
            }
            .validate()
            .is_err()
        );
        assert!(
            ChairsConfig {
                width: 0,
                ..small()
            }
            .validate()
            .is_err()
        );
        assert!(serde_json::from_str::<ChairsConfig>(r#"{"sprite": [1, 2]}"#).is_err());
    }
}
