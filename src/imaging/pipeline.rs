//! The camera: brightness × k → PSF convolution → noise (Eqs. S1–S3) → clamp → gamma (Eq. S4)
//! → quantisation, each stage built only when it would change the image.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use rayon::prelude::*;

use super::config::CameraConfig;
use super::convolve::{ConvMethod, FftConvolver, choose_method, convolve_direct};
use super::noise::NoiseConfig;
use super::tone;
use crate::error::{Error, Result};
use crate::optics::Psf;
use crate::types::Image;

/// One step of the camera model.
pub enum Stage {
    Brightness(f32),
    Blur(Blur),
    Noise(NoiseConfig),
    Clamp,
    Gamma(f32),
    Quantize(u8),
}

impl Stage {
    /// Applies this stage in place; `seed` keys the noise.
    pub fn apply(&self, img: &mut Image, seed: u64) -> Result<()> {
        match self {
            Stage::Brightness(k) => tone::scale(img, *k),
            Stage::Blur(blur) => *img = blur.apply(img)?,
            Stage::Noise(noise) => noise.apply(img, seed),
            Stage::Clamp => tone::clamp01(img),
            Stage::Gamma(g) => tone::gamma(img, *g),
            Stage::Quantize(bits) => tone::quantize(img, *bits),
        }
        Ok(())
    }

    /// The name recorded in manifests.
    pub fn name(&self) -> &'static str {
        match self {
            Stage::Brightness(_) => "brightness",
            Stage::Blur(_) => "psf",
            Stage::Noise(_) => "noise",
            Stage::Clamp => "clamp",
            Stage::Gamma(_) => "gamma",
            Stage::Quantize(_) => "quantize",
        }
    }
}

/// FFT plans are keyed by (channels, height, width) of the image.
type PlanKey = (usize, usize, usize);

/// The PSF stage: the colour PSF, its monochrome version for one-channel images, and the FFT
/// plans prepared per image size.
pub struct Blur {
    psf: Psf,
    mono: Psf,
    method: ConvMethod,
    plans: Mutex<HashMap<PlanKey, Arc<Vec<FftConvolver>>>>,
}

impl Blur {
    fn new(psf: Psf, method: ConvMethod) -> Self {
        let mono = psf.to_mono();
        Self {
            psf,
            mono,
            method,
            plans: Mutex::new(HashMap::new()),
        }
    }

    /// The kernel used for an image of `channels` channels: the mono PSF for a grey image, the
    /// PSF's own channels when they match, its single channel repeated otherwise.
    fn kernel_for(&self, channels: usize) -> Result<&Psf> {
        let k = self.psf.channels();
        if channels == 1 {
            Ok(&self.mono)
        } else if k == channels || k == 1 {
            Ok(&self.psf)
        } else {
            Err(Error::shape(
                "PSF channels for the image",
                format!("1 or {channels}"),
                k,
            ))
        }
    }

    fn apply(&self, image: &Image) -> Result<Image> {
        self.apply_gain(image, 1.0)
    }

    /// Convolves every channel with its PSF, times `gain` (a brightness folded into the blur:
    /// both are linear, so this saves a pass over the frame).
    fn apply_gain(&self, image: &Image, gain: f32) -> Result<Image> {
        let (c, h, w) = image.shape();
        let psf = self.kernel_for(c)?;
        let (kh, kw) = psf.size();
        let method = match self.method {
            ConvMethod::Auto => choose_method(h, w, kh, kw),
            m => m,
        };
        let pick = |ch: usize| if psf.channels() == 1 { 0 } else { ch };
        let mut out = Image::zeros(c, h, w);
        match method {
            ConvMethod::Fft => {
                let plans = self.plans_for(psf, c, h, w);
                out.data_mut()
                    .par_chunks_mut(h * w)
                    .enumerate()
                    .for_each(|(ch, dst)| {
                        plans[pick(ch)].convolve_into(image.plane(ch), gain, dst)
                    });
            }
            _ => out
                .data_mut()
                .par_chunks_mut(h * w)
                .enumerate()
                .for_each(|(ch, dst)| {
                    let plane =
                        convolve_direct(image.plane(ch), h, w, psf.channel(pick(ch)), kh, kw);
                    for (d, v) in dst.iter_mut().zip(plane) {
                        *d = v * gain;
                    }
                }),
        }
        Ok(out)
    }

    fn plans_for(&self, psf: &Psf, channels: usize, h: usize, w: usize) -> Arc<Vec<FftConvolver>> {
        let key = (channels, h, w);
        // A poisoned lock only means another thread panicked mid-insert; the map is still valid.
        let mut plans = self.plans.lock().unwrap_or_else(|e| e.into_inner());
        plans
            .entry(key)
            .or_insert_with(|| {
                let (kh, kw) = psf.size();
                Arc::new(
                    (0..psf.channels())
                        .into_par_iter()
                        .map(|k| FftConvolver::new(psf.channel(k), kh, kw, h, w))
                        .collect(),
                )
            })
            .clone()
    }
}

/// The camera model: an ordered list of stages that are not the identity.
pub struct Camera {
    stages: Vec<Stage>,
    /// γ followed by 8-bit quantisation runs as one exact table lookup (same output).
    fused_tone: Option<super::tone_lut::GammaQuantizer>,
}

impl Camera {
    /// Builds the stages of `config` with an already loaded `psf`. Stages that would change
    /// nothing (brightness 1, a delta PSF, a = b = 0, γ = 1) are left out; the clamp runs only
    /// when an earlier stage can leave [0, 1].
    pub fn new(config: &CameraConfig, psf: Psf) -> Result<Self> {
        config.validate()?;
        let mut stages = Vec::new();
        if config.brightness != 1.0 {
            stages.push(Stage::Brightness(config.brightness));
        }
        if !psf.is_delta() {
            stages.push(Stage::Blur(Blur::new(psf, config.convolution)));
        }
        let noisy = !config.noise.is_identity();
        if noisy {
            stages.push(Stage::Noise(config.noise));
        }
        if noisy || config.brightness > 1.0 {
            stages.push(Stage::Clamp);
        }
        if config.gamma != 1.0 {
            stages.push(Stage::Gamma(config.gamma));
        }
        stages.push(Stage::Quantize(config.bit_depth));
        let fused_tone =
            (config.bit_depth == 8).then(|| super::tone_lut::GammaQuantizer::new(config.gamma));
        Ok(Self { stages, fused_tone })
    }

    /// Names of the stages that run, in order.
    pub fn stage_names(&self) -> Vec<&'static str> {
        self.stages.iter().map(Stage::name).collect()
    }

    /// The stages themselves.
    pub fn stages(&self) -> &[Stage] {
        &self.stages
    }

    /// Images `scene` (linear intensity in [0, 1]) through the camera. `seed` keys the noise.
    pub fn apply(&self, scene: &Image, seed: u64) -> Result<Image> {
        scene.check_nonempty("input image")?;
        scene.check_finite("input image")?;
        // Brightness then blur is one pass (the blur writes a new frame, so no copy either).
        let (mut img, mut i) = match &self.stages[..] {
            [Stage::Brightness(k), Stage::Blur(b), ..] => (b.apply_gain(scene, *k)?, 2),
            [Stage::Blur(b), ..] => (b.apply(scene)?, 1),
            _ => (scene.clone(), 0),
        };
        while i < self.stages.len() {
            // The tail clamp → gamma → quantise(8) is one lookup when the table exists.
            let tail = &self.stages[i..];
            let tone_tail = matches!(
                tail,
                [Stage::Clamp, Stage::Gamma(_), Stage::Quantize(8)]
                    | [Stage::Gamma(_), Stage::Quantize(8)]
                    | [Stage::Clamp, Stage::Quantize(8)]
                    | [Stage::Quantize(8)]
            );
            if tone_tail && let Some(q) = &self.fused_tone {
                let has_gamma = tail.iter().any(|s| matches!(s, Stage::Gamma(_)));
                if has_gamma {
                    q.apply(&mut img);
                } else {
                    tone::quantize(&mut img, 8);
                }
                break;
            }
            self.stages[i].apply(&mut img, seed)?;
            i += 1;
        }
        Ok(img)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gradient(c: usize, h: usize, w: usize) -> Image {
        let mut im = Image::zeros(c, h, w);
        for ch in 0..c {
            for y in 0..h {
                for x in 0..w {
                    im.set(ch, y, x, (x + y + ch) as f32 / (w + h + c) as f32);
                }
            }
        }
        im
    }

    #[test]
    fn identity_stages_are_not_built() {
        let cam = Camera::new(&CameraConfig::ideal(), Psf::delta(3)).unwrap();
        assert_eq!(cam.stage_names(), vec!["quantize"]);
        let full =
            Camera::new(&CameraConfig::default(), Psf::gaussian(3, 2.0, 9).unwrap()).unwrap();
        assert_eq!(
            full.stage_names(),
            vec!["brightness", "psf", "noise", "clamp", "gamma", "quantize"]
        );
    }

    #[test]
    fn ideal_camera_only_quantises() {
        let cam = Camera::new(&CameraConfig::ideal(), Psf::delta(3)).unwrap();
        let im = gradient(3, 8, 8);
        let out = cam.apply(&im, 0).unwrap();
        for (a, b) in im.data().iter().zip(out.data()) {
            assert!((a - b).abs() <= 0.5 / 255.0 + 1e-7);
        }
    }

    #[test]
    fn extreme_images_give_finite_in_range_output() {
        let cam = Camera::new(
            &CameraConfig::default(),
            Psf::gaussian(3, 30.0, 129).unwrap(),
        )
        .unwrap();
        for value in [0.0f32, 1.0, 0.5] {
            let out = cam.apply(&Image::filled(3, 20, 24, value), 5).unwrap();
            assert!(
                out.data()
                    .iter()
                    .all(|v| v.is_finite() && (0.0..=1.0).contains(v))
            );
        }
        let mut bad = Image::filled(1, 4, 4, 0.2);
        bad.set(0, 1, 1, f32::INFINITY);
        assert!(cam.apply(&bad, 0).is_err());
    }

    #[test]
    fn grey_image_convolves_one_channel_with_the_mono_psf() {
        let cam = Camera::new(
            &CameraConfig {
                noise: NoiseConfig {
                    a: 0.0,
                    b: 0.0,
                    ..Default::default()
                },
                ..CameraConfig::default()
            },
            Psf::gaussian(3, 1.5, 9).unwrap(),
        )
        .unwrap();
        let out = cam.apply(&gradient(1, 16, 16), 0).unwrap();
        assert_eq!(out.channels(), 1);
    }

    #[test]
    fn direct_and_fft_pipelines_agree() {
        let psf = Psf::gaussian(3, 3.0, 15).unwrap();
        let im = gradient(3, 40, 50);
        let mk = |m| {
            let cfg = CameraConfig {
                convolution: m,
                bit_depth: 16,
                ..CameraConfig::default()
            };
            Camera::new(&cfg, psf.clone())
                .unwrap()
                .apply(&im, 9)
                .unwrap()
        };
        let (d, f) = (mk(ConvMethod::Direct), mk(ConvMethod::Fft));
        let max = d
            .data()
            .iter()
            .zip(f.data())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f32::max);
        assert!(max <= 1.0 / 65535.0 + 1e-7, "max diff {max}");
    }
}
