//! Trajectory clips on disk (Movies S1–S2): every frame of a trajectory scene through the
//! camera model as `frames/NNNNN.png`, the exact flow from frame n to n + 1 as
//! `flows/NNNNN.flo`, the ground-truth centres as `truth.json` and the config as `config.json`.

use std::path::Path;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::imaging::{Camera, CameraConfig, psf_source};
use crate::io::{self, BitDepth};
use crate::rng;
use crate::scene::trajectory::TrajectoryConfig;
use crate::scene::truth::Truth;

/// A clip: the scene and the camera it is seen through.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SequenceConfig {
    pub scene: TrajectoryConfig,
    pub camera: CameraConfig,
    /// Also write the frames before the camera (`clean/NNNNN.png`, 16-bit).
    pub save_clean: bool,
}

impl SequenceConfig {
    /// Reads a JSON config; relative PSF paths are relative to the file.
    pub fn from_file(path: &Path) -> Result<Self> {
        let mut cfg: Self = io::read_json(path)?;
        cfg.camera
            .resolve_paths(path.parent().unwrap_or(Path::new("")));
        cfg.validate().map_err(|e| io::in_config(path, e))?;
        Ok(cfg)
    }

    pub fn validate(&self) -> Result<()> {
        self.scene.validate()?;
        self.camera.validate()
    }

    /// The camera of this clip.
    pub fn camera(&self) -> Result<Camera> {
        let (psf, _) = psf_source::load(&self.camera.psf)?;
        Camera::new(&self.camera, psf)
    }
}

/// Renders the clip into `dir` (frames, flows, truth, config) and returns its ground truth.
/// Every file is written atomically and every byte depends on the config alone.
pub fn render_sequence(cfg: &SequenceConfig, dir: &Path) -> Result<Truth> {
    cfg.validate()?;
    let camera = cfg.camera()?;
    let truth = Truth::of(&cfg.scene)?;
    let depth = if cfg.camera.bit_depth == 16 {
        BitDepth::Sixteen
    } else {
        BitDepth::Eight
    };
    let scene = &cfg.scene;
    claim(cfg, dir)?;
    for sub in ["frames", "flows"] {
        std::fs::create_dir_all(dir.join(sub)).map_err(|e| Error::io(dir.join(sub), e))?;
    }
    // The config first, so a run stopped halfway can be repeated into the same folder;
    // truth.json last, so its presence means every frame and flow is there.
    io::write_bytes_atomic(&dir.join("config.json"), json(cfg)?.as_bytes())?;
    if cfg.save_clean {
        std::fs::create_dir_all(dir.join("clean")).map_err(|e| Error::io(dir.join("clean"), e))?;
    }
    (0..scene.frames)
        .into_par_iter()
        .try_for_each(|n| -> Result<()> {
            let clean = scene.frame(n)?;
            let seed = rng::derive(scene.seed, &[rng::purpose::NOISE_FRAME1, n as u64]);
            let img = camera.apply(&clean, seed)?;
            io::write_image(&dir.join("frames").join(format!("{n:05}.png")), &img, depth)?;
            if cfg.save_clean {
                io::write_image(
                    &dir.join("clean").join(format!("{n:05}.png")),
                    &clean,
                    BitDepth::Sixteen,
                )?;
            }
            if n + 1 < scene.frames {
                io::write_flo(
                    &dir.join("flows").join(format!("{n:05}.flo")),
                    &scene.flow(n)?,
                )?;
            }
            Ok(())
        })?;
    io::write_bytes_atomic(&dir.join("truth.json"), json(&truth)?.as_bytes())?;
    Ok(truth)
}

/// A clip folder holds one clip: rendering into a folder that holds another (a different
/// `config.json`, or frames without one) would mix their frames, so it is refused.
fn claim(cfg: &SequenceConfig, dir: &Path) -> Result<()> {
    let existing = dir.join("config.json");
    if existing.exists() {
        let text = std::fs::read_to_string(&existing).map_err(|e| Error::io(&existing, e))?;
        let same = serde_json::from_str::<SequenceConfig>(&text).is_ok_and(|c| c == *cfg);
        if !same {
            return Err(Error::invalid(
                "--out",
                format!(
                    "{} holds another clip (its config.json differs); choose an empty folder",
                    dir.display()
                ),
            ));
        }
    } else if ["frames", "flows"]
        .iter()
        .any(|sub| std::fs::read_dir(dir.join(sub)).is_ok_and(|mut d| d.next().is_some()))
    {
        return Err(Error::invalid(
            "--out",
            format!(
                "{} already holds frames or flows without a config.json; choose an empty folder",
                dir.display()
            ),
        ));
    }
    Ok(())
}

fn json(v: &impl Serialize) -> Result<String> {
    serde_json::to_string_pretty(v).map_err(|e| Error::invalid("json", e.to_string()))
}
