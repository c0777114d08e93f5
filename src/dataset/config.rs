//! The generator's configuration: which scenes, which camera, how many samples, which seed.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::imaging::CameraConfig;
use crate::scene::ChairsConfig;
use crate::scene::patterns::RocketStep;

/// The scene family of a dataset.
// One config per run: the size of the largest variant does not matter.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum SceneSpec {
    /// FlyingChairs-like layered scenes.
    Chairs(ChairsConfig),
    /// Camouflaged discs moving over a still background (the tracking clips' scenes).
    Movers(crate::scene::MoversConfig),
    /// The Note S12 rocket moved by 3 px in one direction.
    Rocket {
        step: RocketStep,
        #[serde(default = "one")]
        channels: usize,
    },
    /// A Note S12 disc of `radius` px moving 15 px right.
    Disc {
        radius: f64,
        #[serde(default = "one")]
        channels: usize,
    },
    /// Image pairs and flows of an existing dataset on disk, passed through the camera.
    Dataset {
        path: std::path::PathBuf,
        #[serde(default)]
        layout: crate::scene::readers::Layout,
    },
}

fn one() -> usize {
    1
}

/// A whole generator run. Unknown keys are rejected at every level.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GeneratorConfig {
    /// Number of samples.
    pub count: usize,
    /// Master seed; sample `i` uses a seed derived from (seed, i) alone.
    pub seed: u64,
    pub scene: SceneSpec,
    pub camera: CameraConfig,
    /// Also write the ideal images before the camera (`NNNNN_clean1.png`, 16-bit).
    pub save_clean: bool,
}

impl Default for GeneratorConfig {
    fn default() -> Self {
        Self {
            count: 64,
            seed: 0,
            scene: SceneSpec::Chairs(ChairsConfig::default()),
            camera: CameraConfig::default(),
            save_clean: false,
        }
    }
}

impl GeneratorConfig {
    /// Reads a JSON config; the error names the file and the offending key or value.
    pub fn from_file(path: &Path) -> Result<Self> {
        let mut cfg: Self = crate::io::read_json(path)?;
        // Relative paths inside a config are relative to the config file, not to the caller's
        // working directory, so experiment files work from anywhere.
        let base = path.parent().unwrap_or(Path::new(""));
        if let SceneSpec::Dataset { path: p, .. } = &mut cfg.scene
            && p.is_relative()
        {
            *p = base.join(&*p);
        }
        if let SceneSpec::Chairs(c) = &mut cfg.scene
            && let Some(photos) = &mut c.photos
        {
            photos.resolve_paths(base);
        }
        cfg.camera.resolve_paths(base);
        cfg.validate().map_err(|e| crate::io::in_config(path, e))?;
        Ok(cfg)
    }

    /// Checks every section.
    pub fn validate(&self) -> Result<()> {
        if self.count == 0 || self.count > 10_000_000 {
            return Err(Error::invalid(
                "count",
                format!("must be 1..=10000000, got {}", self.count),
            ));
        }
        self.camera.validate()?;
        match &self.scene {
            SceneSpec::Chairs(c) => c.validate(),
            SceneSpec::Movers(m) => m.validate(),
            SceneSpec::Rocket { channels, .. } | SceneSpec::Disc { channels, .. }
                if *channels != 1 && *channels != 3 =>
            {
                Err(Error::invalid(
                    "scene.channels",
                    format!("must be 1 or 3, got {channels}"),
                ))
            }
            SceneSpec::Disc { radius, .. } => {
                crate::scene::patterns::disc(*radius, 1, crate::scene::patterns::S12_SIZE)
                    .map(|_| ())
            }
            _ => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_nested_configs_and_rejects_unknown_keys() {
        let cfg: GeneratorConfig = serde_json::from_str(
            r#"{"count": 3, "scene": {"kind": "chairs", "width": 64, "height": 48}, "camera": {"gamma": 1.5}}"#,
        )
        .unwrap();
        cfg.validate().unwrap();
        assert_eq!(cfg.camera.gamma, 1.5);
        assert!(
            matches!(cfg.scene, SceneSpec::Chairs(ref c) if c.width == 64 && c.sprites == [3, 8])
        );
        for bad in [
            r#"{"cout": 3}"#,
            r#"{"scene": {"kind": "chairs", "widht": 64}}"#,
            r#"{"scene": {"kind": "teapot"}}"#,
            r#"{"camera": {"noise": {"c": 1}}}"#,
        ] {
            assert!(
                serde_json::from_str::<GeneratorConfig>(bad).is_err(),
                "{bad}"
            );
        }
        let zero: GeneratorConfig = serde_json::from_str(r#"{"count": 0}"#).unwrap();
        assert!(zero.validate().is_err());
    }
}
