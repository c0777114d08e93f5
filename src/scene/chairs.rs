//! FlyingChairs-like procedural scenes: a textured background under a small global affine
//! motion and textured blob sprites under independent translations, rotations and scalings,
//! with the variety real cameras see as options: photographic textures, motions from sub-pixel
//! to 100+ px, still backgrounds and objects, small sprites, dark and low-contrast scenes, and a
//! road under a camera driving ahead (`scene::ground`).

use std::f64::consts::PI;
use std::sync::Arc;

use rand::RngExt;
use serde::{Deserialize, Serialize};

use super::affine::Affine;
use super::ground::{FAR, FAR_MIN, Ground};
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
            brightness: [1.0, 1.0],
            contrast: [1.0, 1.0],
            ground: 0.0,
            ground_advance: [0.05, 0.4],
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

        // The ground, from its own stream: a config without it draws the scenes it always drew.
        let mut g = rng::stream(seed, &[rng::purpose::SCENE, rng::purpose::GROUND]);
        // A still camera (`still_background`) sees its ground stand still too: none is drawn.
        if self.ground > 0.0 && g.random::<f64>() < self.ground && !still_background {
            let ground = Ground {
                f: w * g.random_range(0.5..0.8),
                cx: w * g.random_range(0.4..0.6),
                horizon: h * g.random_range(0.3..0.45),
                height: h,
                advance: uniform(&mut g, self.ground_advance),
                slide: g.random_range(-0.1..=0.1),
                turn: g.random_range(-1.5..=1.5f64).to_radians(),
            };
            // The patch: from just below the bottom row to FAR times as deep, wide enough to
            // fill the frame at its far edge after the slide and the turn.
            let (near, far) = (0.97 * ground.near(), FAR * ground.near());
            let half = 1.2 * w / ground.f * far + 0.1;
            // At most 1536 texture pixels on the patch's longer side.
            let metres = (2.0 * half).max(far - near) / 1536.0;
            let (tw, th) = ((2.0 * half / metres).ceil(), ((far - near) / metres).ceil());
            let tex_seed = g.random();
            let tex = texture(
                &mut g,
                false,
                tex_seed,
                th as usize,
                tw as usize,
                short as f32,
            );
            let z_centre = 0.5 * (near + far);
            let (u, v) = (half / metres, 0.5 * (far - near) / metres);
            let [p1, p2] = ground.poses(metres, z_centre);
            // The near edge below the bottom row; the far edge uneven, seven points each
            // FAR_MIN..FAR times the nearest depth (a skyline, not one straight boundary).
            let mut vertices = vec![(-u, v), (u, v)];
            for k in 0..7 {
                let z = ground.near() * g.random_range(FAR_MIN..=FAR);
                vertices.push((u - 2.0 * u * k as f64 / 6.0, (z_centre - z) / metres));
            }
            layers.push(Layer {
                shape: Shape::Polygon { vertices },
                fill: Fill::Texture {
                    image: Arc::new(tex),
                    origin: (tw / 2.0, th / 2.0),
                },
                poses: [p1.into(), p2.into()],
            });
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
            let shape = Shape::Blob { radius, harmonics };
            let bound = shape.bound_radius();
            let size = (2.0 * bound * 1.3).ceil().max(4.0) as usize + 2;
            let tex_seed = r.random();
            let (x, y) = (r.random_range(-0.1..1.1) * w, r.random_range(-0.1..1.1) * h);
            let (theta, s) = (r.random_range(0.0..2.0 * PI), r.random_range(0.85..1.15));
            let (dx, dy) = self.translation(r, self.max_translation);
            let dtheta = r.random_range(-1.0..=1.0) * self.max_rotation_deg.to_radians();
            let ds = uniform(r, self.scale_change);
            let still = self.still_sprites > 0.0 && v.random::<f64>() < self.still_sprites;
            let tex = texture(&mut v, false, tex_seed, size, size, (2.0 * radius) as f32);
            let pose1 = Affine::pose(x, y, theta, s);
            layers.push(Layer {
                shape,
                fill: Fill::Texture {
                    image: Arc::new(tex),
                    origin: (size as f64 / 2.0, size as f64 / 2.0),
                },
                poses: [
                    pose1.into(),
                    if still {
                        pose1
                    } else {
                        Affine::pose(x + dx, y + dy, theta + dtheta, s * ds)
                    }
                    .into(),
                ],
            });
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

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

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
    fn a_still_camera_and_still_sprites_make_a_static_scene() {
        let cfg = ChairsConfig {
            still_background: 1.0,
            still_sprites: 1.0,
            ..small()
        };
        let (scene, draw) = cfg.build_recorded(4).unwrap();
        assert!(draw.still_background);
        assert!(scene.is_static());
        // A still background alone: the flow is exactly zero wherever the background shows.
        let cfg = ChairsConfig {
            still_background: 1.0,
            sprites: [1, 1],
            sprite_radius: [0.1, 0.1],
            ..small()
        };
        let flow = cfg.build(4).unwrap().flow().unwrap();
        let zero = (0..48)
            .flat_map(|y| (0..64).map(move |x| (y, x)))
            .filter(|&(y, x)| flow.get(y, x) == (0.0, 0.0))
            .count();
        assert!(zero > 64 * 48 / 2, "{zero} still pixels");
        assert!(flow.max_magnitude() > 0.0);
    }

    #[test]
    fn the_log_uniform_law_spans_sub_pixel_to_large_motions() {
        let cfg = ChairsConfig {
            translation_law: TranslationLaw::LogUniform,
            min_translation: 0.1,
            max_translation: 128.0,
            ..small()
        };
        let mut r = rng::stream(1, &[9]);
        let lens: Vec<f64> = (0..4000)
            .map(|_| {
                let (x, y) = cfg.translation(&mut r, 128.0);
                x.hypot(y)
            })
            .collect();
        assert!(
            lens.iter()
                .all(|&l| (0.1 - 1e-9..=128.0 + 1e-9).contains(&l))
        );
        // Log-uniform: each of the ten octaves holds about a tenth of the draws.
        let below_1 = lens.iter().filter(|&&l| l < 1.0).count() as f64 / 4000.0;
        let above_32 = lens.iter().filter(|&&l| l > 32.0).count() as f64 / 4000.0;
        let octave = 1.0 / (1280.0f64).log2();
        assert!((below_1 - 10f64.log2() * octave).abs() < 0.04, "{below_1}");
        assert!((above_32 - 2.0 * octave).abs() < 0.04, "{above_32}");
    }

    #[test]
    fn knobs_are_drawn_apart_from_the_geometry() {
        // Tone and still sprites change what is drawn, not where: the first frame's layer
        // geometry is that of the plain config.
        let plain = small();
        let knobs = ChairsConfig {
            still_sprites: 0.5,
            brightness: [0.3, 0.6],
            contrast: [0.5, 0.9],
            ..small()
        };
        assert!(!plain.has_variety() && knobs.has_variety());
        let (a, b) = (plain.build(8).unwrap(), knobs.build(8).unwrap());
        let (ra, rb) = (a.records(), b.records());
        assert_eq!(ra.len(), rb.len());
        for (x, y) in ra.iter().zip(&rb) {
            assert_eq!(x.poses[0], y.poses[0]);
        }
        // Darker and flatter, within [0, 1].
        let (ia, ib) = (a.render(0).unwrap(), b.render(0).unwrap());
        let mean = |d: &[f32]| d.iter().map(|&v| v as f64).sum::<f64>() / d.len() as f64;
        assert!(mean(ib.data()) < 0.75 * mean(ia.data()));
        assert!(ib.data().iter().all(|v| (0.0..=1.0).contains(v)));
    }

    #[test]
    fn small_sprites_and_photo_textures_are_recorded() {
        let photos = Path::new(env!("CARGO_MANIFEST_DIR")).join("datasets/photos/train");
        let cfg = ChairsConfig {
            sprites: [1, 1],
            small_sprites: [3, 3],
            small_sprite_radius_px: [3.0, 3.0],
            photos: Some(PhotoTextures {
                dirs: vec![photos],
                fraction: 1.0,
                ..PhotoTextures::default()
            }),
            ..small()
        };
        let (scene, draw) = cfg.build_recorded(2).unwrap();
        assert_eq!(scene.layers.len(), 1 + 1 + 3);
        assert_eq!(draw.textures.len(), 5);
        assert!(draw.textures.iter().all(|t| t.is_some()));
        for layer in &scene.layers[2..] {
            assert!(matches!(layer.shape, Shape::Blob { radius, .. } if radius == 3.0));
        }
        assert_eq!(cfg.build_recorded(2).unwrap().1, draw);
        let half = ChairsConfig {
            photos: Some(PhotoTextures {
                fraction: 0.5,
                ..cfg.photos.clone().unwrap()
            }),
            small_sprites: [20, 20],
            ..cfg.clone()
        };
        let textures = half.build_recorded(3).unwrap().1.textures;
        let photo = textures.iter().filter(|t| t.is_some()).count();
        assert!(
            photo > 3 && photo < textures.len() - 3,
            "{photo} of {}",
            textures.len()
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

    /// A ground plane under a camera driving ahead: below the patch's far edge the flow points
    /// down and grows row by row to the bottom, where it is (H − horizon)·a/(1 − a) at most;
    /// frame 2 at x + flow shows what frame 1 shows at x; the far world above does not move;
    /// the same seed without the ground draws the same layers otherwise.
    #[test]
    fn a_ground_plane_flows_down_and_out_and_its_frames_agree() {
        let still_world = ChairsConfig {
            width: 160,
            height: 120,
            supersample: 2,
            sprites: [0, 0],
            background_translation: 0.0,
            background_rotation_deg: 0.0,
            background_zoom: [1.0, 1.0],
            ..ChairsConfig::default()
        };
        let cfg = ChairsConfig {
            ground: 1.0,
            ground_advance: [0.2, 0.3],
            ..still_world.clone()
        };
        for seed in [3u64, 4, 5] {
            let scene = cfg.build(seed).unwrap();
            assert_eq!(scene.layers.len(), 2, "background and ground");
            let flow = scene.flow().unwrap();
            // The mean downward flow of each row.
            let row_v: Vec<f64> = (0..120)
                .map(|y| (0..160).map(|x| flow.get(y, x).1 as f64).sum::<f64>() / 160.0)
                .collect();
            assert!(
                row_v[..30].iter().all(|v| v.abs() < 1e-9),
                "{:?}",
                &row_v[..30]
            );
            let bottom = row_v[119];
            assert!(
                bottom > 5.0 && bottom <= 0.7 * 120.0 * 0.3 / 0.7 + 1.0,
                "{bottom}"
            );
            for y in 100..119 {
                assert!(
                    row_v[y] < row_v[y + 1],
                    "row {y}: {} then {}",
                    row_v[y],
                    row_v[y + 1]
                );
            }
            // Brightness constancy where the ground stays in the frame.
            let (f1, f2) = (scene.render(0).unwrap(), scene.render(1).unwrap());
            let (mut moved, mut still, mut n) = (0.0, 0.0, 0);
            for y in 70..110 {
                for x in 30..130 {
                    let (u, v) = flow.get(y, x);
                    let (x2, y2) = (x as f32 + u, y as f32 + v);
                    if !(0.0..158.0).contains(&x2) || !(0.0..118.0).contains(&y2) {
                        continue;
                    }
                    for c in 0..3 {
                        let a = f1.get(c, y, x);
                        moved += (super::super::texture::sample_bilinear(&f2, c, x2, y2) - a).abs()
                            as f64;
                        still += (f2.get(c, y, x) - a).abs() as f64;
                        n += 1;
                    }
                }
            }
            assert!(n > 3000, "{n}");
            let (moved, still) = (moved / n as f64, still / n as f64);
            assert!(
                moved < 0.3 * still,
                "seed {seed}: {moved} along the flow, {still} in place"
            );
            // Without the ground: the same background.
            let plain = still_world.build(seed).unwrap();
            assert_eq!(plain.records()[0], scene.records()[0]);
        }
        let bad = ChairsConfig {
            ground_advance: [0.2, 0.9],
            ..cfg
        };
        assert!(
            bad.validate()
                .unwrap_err()
                .to_string()
                .contains("scene.ground_advance")
        );
    }
}
