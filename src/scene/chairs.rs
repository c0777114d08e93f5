//! FlyingChairs-like procedural scenes: a textured background under a small global affine
//! motion and textured blob sprites under independent translations, rotations and scalings,
//! with the variety real cameras see as options: photographic textures, motions from sub-pixel
//! to 100+ px, still backgrounds and objects, small and flat sprites, dark and low-contrast
//! scenes, and a road under a camera driving ahead with boxes standing on it (`chairs::road`).

use std::f64::consts::PI;
use std::sync::Arc;

use rand::RngExt;
use serde::{Deserialize, Serialize};

use super::affine::Affine;
use super::layered::{Fill, Layer, LayeredScene};
use super::photos::{PhotoCrop, PhotoTextures};
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
    /// Photographs as textures, mixed with the procedural ones (none by default).
    pub photos: Option<PhotoTextures>,
    /// How translation lengths are drawn, for sprites and background alike.
    pub translation_law: TranslationLaw,
    /// Shortest translation of the `log_uniform` law, pixels.
    pub min_translation: f64,
    /// Share of samples whose background stands still (a fixed camera).
    pub still_background: f64,
    /// Share of sprites that stand still.
    pub still_sprites: f64,
    /// Share of samples whose background is one flat colour and stands still (a night sky, a
    /// blank wall: nothing there to see move, so the true flow is zero).
    pub plain_background: f64,
    /// Extra small sprites per sample, drawn on top of the others (Note S12's sizes).
    pub small_sprites: [usize; 2],
    /// Radius of the small sprites, pixels.
    pub small_sprite_radius_px: [f64; 2],
    /// Share of sprites (small ones too) painted one flat colour, stretched 1–4× along their
    /// own axis, each with 0–2 flat marks that move with it (a window, a decal): objects whose
    /// inside has nothing to match, so their motion must be read from their ends and marks
    /// (Note S12's rocket and discs; `chairs::flat`).
    pub flat_sprites: f64,
    /// Gain applied to every texture before the camera, drawn per sample.
    pub brightness: [f64; 2],
    /// Contrast about mid-grey applied to every texture before the camera, drawn per sample.
    pub contrast: [f64; 2],
    /// Share of samples with a ground plane over the background's lower part: a road under a
    /// camera that drives ahead, whose flow grows from the horizon to the bottom row (KITTI's
    /// perspective, which no similarity of the background gives). Samples whose background
    /// stands still (`still_background`, `plain_background`) have none.
    pub ground: f64,
    /// The camera's advance between the frames, as a share of the distance to the nearest
    /// ground it sees: the bottom row moves (H − horizon)·a/(1 − a) px.
    pub ground_advance: [f64; 2],
    /// Boxes standing on a sample's ground (parked cars, vans, posts, walls: 0.3–2.5 m wide,
    /// 0.3–8 m long, 0.3–3.5 m tall), still in the world, so that each face moves with the
    /// camera's motion at its own depth and hides the road behind it; their count per ground.
    pub ground_objects: [usize; 2],
}

/// The law of translation lengths.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TranslationLaw {
    /// Uniform over the disc of radius `max` (most translations near the largest).
    #[default]
    Disc,
    /// Length log-uniform in `[min_translation, max]`, direction uniform: every octave of
    /// motion, sub-pixel to large, is equally common (AutoFlow's lesson).
    LogUniform,
}

/// What a sample drew beyond its layers' geometry, for its metadata.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ChairsDraw {
    pub still_background: bool,
    /// The background is one flat colour (its texture entry is `null`).
    #[serde(default)]
    pub plain_background: bool,
    pub brightness: f64,
    pub contrast: f64,
    /// Per layer, bottom to top: `null` for a procedural texture, else the photo window.
    pub textures: Vec<Option<PhotoCrop>>,
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
            photos: None,
            translation_law: TranslationLaw::Disc,
            min_translation: 0.05,
            still_background: 0.0,
            still_sprites: 0.0,
            plain_background: 0.0,
            small_sprites: [0, 0],
            small_sprite_radius_px: [2.0, 10.0],
            flat_sprites: 0.0,
            brightness: [1.0, 1.0],
            contrast: [1.0, 1.0],
            ground: 0.0,
            ground_advance: [0.05, 0.4],
            ground_objects: [0, 0],
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
        if let Some(p) = &self.photos {
            p.validate()?;
        }
        if !(self.min_translation.is_finite() && self.min_translation > 0.0) {
            return Err(Error::invalid(
                "scene.min_translation",
                format!("must be finite and > 0, got {}", self.min_translation),
            ));
        }
        for (name, v) in [
            ("scene.still_background", self.still_background),
            ("scene.still_sprites", self.still_sprites),
            ("scene.plain_background", self.plain_background),
            ("scene.flat_sprites", self.flat_sprites),
            ("scene.ground", self.ground),
        ] {
            if !(0.0..=1.0).contains(&v) {
                return Err(Error::invalid(name, format!("must be in [0, 1], got {v}")));
            }
        }
        if self.small_sprites[0] > self.small_sprites[1] || self.small_sprites[1] > 256 {
            return Err(Error::invalid(
                "scene.small_sprites",
                format!("expected min <= max <= 256, got {:?}", self.small_sprites),
            ));
        }
        check_range(
            "scene.small_sprite_radius_px",
            self.small_sprite_radius_px,
            0.5,
            1000.0,
        )?;
        check_range("scene.brightness", self.brightness, 0.0, 10.0)?;
        check_range("scene.contrast", self.contrast, 0.0, 10.0)?;
        check_range("scene.ground_advance", self.ground_advance, 0.0, 0.8)?;
        if self.ground_objects[0] > self.ground_objects[1] || self.ground_objects[1] > 32 {
            return Err(Error::invalid(
                "scene.ground_objects",
                format!("expected min <= max <= 32, got {:?}", self.ground_objects),
            ));
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
        Ok(self.build_recorded(seed)?.0)
    }

    /// True when a knob beyond the original FlyingChairs recipe is on: such samples record
    /// their [`ChairsDraw`] in their metadata.
    pub fn has_variety(&self) -> bool {
        self.photos.is_some()
            || self.translation_law != TranslationLaw::Disc
            || self.still_background > 0.0
            || self.still_sprites > 0.0
            || self.plain_background > 0.0
            || self.small_sprites[1] > 0
            || self.flat_sprites > 0.0
            || self.brightness != [1.0, 1.0]
            || self.contrast != [1.0, 1.0]
            || self.ground > 0.0
    }

    /// Draws the scene for `seed` and what it drew beyond the layers' geometry.
    ///
    /// The geometry comes from one random stream and every optional knob from a second one,
    /// so a config without them draws exactly the scenes it always drew.
    pub fn build_recorded(&self, seed: u64) -> Result<(LayeredScene, ChairsDraw)> {
        self.validate()?;
        let mut r = rng::stream(seed, &[rng::purpose::SCENE]);
        let mut v = rng::stream(seed, &[rng::purpose::SCENE, rng::purpose::VARIETY]);
        let library = match &self.photos {
            Some(p) => Some(p.library()?),
            None => None,
        };
        let brightness = uniform(&mut v, self.brightness);
        let contrast = uniform(&mut v, self.contrast);
        let mut still_background =
            self.still_background > 0.0 && v.random::<f64>() < self.still_background;
        let plain_background =
            self.plain_background > 0.0 && v.random::<f64>() < self.plain_background;
        still_background |= plain_background;
        let mut textures = Vec::new();
        // A texture: procedural from `seed`, or (with the photos' probability) cut from a photo,
        // or one flat colour when `plain`.
        let mut texture =
            |v: &mut rng::Rng, plain: bool, seed: u64, h: usize, w: usize, scale: f32| {
                let (mut img, crop) = match (&self.photos, &library) {
                    _ if plain => {
                        let mut img = crate::types::Image::zeros(self.channels, h, w);
                        for c in 0..self.channels {
                            img.plane_mut(c).fill(v.random::<f32>());
                        }
                        (img, None)
                    }
                    (Some(p), Some(lib)) if v.random::<f64>() < p.fraction => {
                        let (img, crop) = p.cut(lib, v, self.channels, h, w);
                        (img, Some(crop))
                    }
                    _ => (procedural(seed, self.channels, h, w, scale), None),
                };
                tone(&mut img, brightness, contrast);
                textures.push(crop);
                img
            };
        let (w, h) = (self.width as f64, self.height as f64);
        let short = w.min(h);
        let mut layers = Vec::new();

        // Background: a texture a quarter larger than the frame, moved about the frame centre.
        let (tw, th) = ((w * 1.25).ceil() as usize, (h * 1.25).ceil() as usize);
        let bg_tex = texture(&mut v, plain_background, r.random(), th, tw, short as f32);
        let pose1 = Affine::translation(w / 2.0, h / 2.0);
        let centre_motion = {
            let (dx, dy) = self.translation(&mut r, self.background_translation);
            let theta = r.random_range(-1.0..=1.0) * self.background_rotation_deg.to_radians();
            let zoom = uniform(&mut r, self.background_zoom);
            if still_background {
                Affine::IDENTITY
            } else {
                Affine::translation(w / 2.0 + dx, h / 2.0 + dy)
                    .compose(&Affine::pose(0.0, 0.0, theta, zoom))
                    .compose(&Affine::translation(-w / 2.0, -h / 2.0))
            }
        };
        layers.push(Layer {
            shape: Shape::Full,
            fill: Fill::Texture {
                image: Arc::new(bg_tex),
                origin: (tw as f64 / 2.0, th as f64 / 2.0),
            },
            poses: [pose1.into(), centre_motion.compose(&pose1).into()],
        });

        // The ground and what stands on it, from their own streams: a config without them draws
        // the scenes it always drew. A still camera (`still_background`) sees its ground stand
        // still too: none is drawn.
        if !still_background {
            layers.extend(road::draw(self, seed, &mut texture));
        }

        let count = r.random_range(self.sprites[0]..=self.sprites[1]);
        let small = if self.small_sprites[1] > 0 {
            v.random_range(self.small_sprites[0]..=self.small_sprites[1])
        } else {
            0
        };
        for k in 0..count + small {
            // The small sprites draw everything from the second stream.
            let r = if k < count { &mut r } else { &mut v };
            let radius = if k < count {
                uniform(r, self.sprite_radius) * short
            } else {
                uniform(r, self.small_sprite_radius_px)
            };
            let harmonics: Vec<(u32, f64, f64)> = (2..=5)
                .map(|k| {
                    (
                        k,
                        r.random_range(0.0..0.25) / (k as f64 - 1.0),
                        r.random_range(0.0..2.0 * PI),
                    )
                })
                .collect();
            let tex_seed = r.random();
            let (x, y) = (r.random_range(-0.1..1.1) * w, r.random_range(-0.1..1.1) * h);
            let (theta, s) = (r.random_range(0.0..2.0 * PI), r.random_range(0.85..1.15));
            let (dx, dy) = self.translation(r, self.max_translation);
            let dtheta = r.random_range(-1.0..=1.0) * self.max_rotation_deg.to_radians();
            let ds = uniform(r, self.scale_change);
            let still = self.still_sprites > 0.0 && v.random::<f64>() < self.still_sprites;
            let flat = self.flat_sprites > 0.0 && v.random::<f64>() < self.flat_sprites;
            let (shape, marks) = if flat {
                let f = flat::draw(radius, &harmonics, &mut v);
                (f.shape, f.marks)
            } else {
                (Shape::Blob { radius, harmonics }, Vec::new())
            };
            let size = (2.0 * shape.bound_radius() * 1.3).ceil().max(4.0) as usize + 2;
            let tex = texture(&mut v, flat, tex_seed, size, size, (2.0 * radius) as f32);
            let pose1 = Affine::pose(x, y, theta, s);
            let pose2 = if still {
                pose1
            } else {
                Affine::pose(x + dx, y + dy, theta + dtheta, s * ds)
            };
            layers.push(Layer {
                shape,
                fill: Fill::Texture {
                    image: Arc::new(tex),
                    origin: (size as f64 / 2.0, size as f64 / 2.0),
                },
                poses: [pose1.into(), pose2.into()],
            });
            // A flat sprite's marks ride on its poses.
            for (mark, (cx, cy)) in marks {
                let offset = Affine::translation(cx, cy);
                let side = (2.0 * mark).ceil() as usize + 2;
                let tex = texture(&mut v, true, 0, side, side, 1.0);
                layers.push(Layer {
                    shape: Shape::Disc { radius: mark },
                    fill: Fill::Texture {
                        image: Arc::new(tex),
                        origin: (side as f64 / 2.0, side as f64 / 2.0),
                    },
                    poses: [pose1.compose(&offset).into(), pose2.compose(&offset).into()],
                });
            }
        }
        let draw = ChairsDraw {
            still_background,
            plain_background,
            brightness,
            contrast,
            textures,
        };
        Ok((
            LayeredScene {
                width: self.width,
                height: self.height,
                channels: self.channels,
                layers,
                supersample: self.supersample,
            },
            draw,
        ))
    }

    /// A translation of at most `max` pixels under the configured law.
    fn translation(&self, r: &mut rng::Rng, max: f64) -> (f64, f64) {
        match self.translation_law {
            TranslationLaw::Disc => disc_sample(r, max),
            TranslationLaw::LogUniform => {
                if max <= self.min_translation {
                    return disc_sample(r, max);
                }
                let len = r.random_range(self.min_translation.ln()..=max.ln()).exp();
                let phi = r.random_range(0.0..2.0 * PI);
                (len * phi.cos(), len * phi.sin())
            }
        }
    }
}

/// Gain and contrast about mid-grey, clamped to [0, 1]: the scene's own exposure and contrast
/// before the camera.
fn tone(img: &mut crate::types::Image, gain: f64, contrast: f64) {
    if gain == 1.0 && contrast == 1.0 {
        return;
    }
    let (g, c) = (gain as f32, contrast as f32);
    for x in img.data_mut() {
        *x = (g * (0.5 + c * (*x - 0.5))).clamp(0.0, 1.0);
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

mod flat;
mod road;
#[cfg(test)]
mod tests;
