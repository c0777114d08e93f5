//! The dataset manifest and the per-sample metadata sidecars it is assembled from (every
//! parameter that made a sample, so it can be regenerated exactly, as Kubric records them).

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::config::GeneratorConfig;
use crate::error::{Error, Result};
use crate::io;
use crate::scene::layered::LayerRecord;
use crate::types::Flow;

/// Summary statistics of a ground-truth flow over its known vectors.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FlowStats {
    pub mean_magnitude: f64,
    pub max_magnitude: f64,
    pub valid_fraction: f64,
}

impl FlowStats {
    pub fn of(flow: &Flow) -> Self {
        let (mut sum, mut max, mut n) = (0.0f64, 0.0f64, 0usize);
        for (u, v) in flow.u().iter().zip(flow.v()) {
            if u.is_finite() && v.is_finite() {
                let m = ((u * u + v * v) as f64).sqrt();
                sum += m;
                max = max.max(m);
                n += 1;
            }
        }
        let total = (flow.height() * flow.width()).max(1);
        Self {
            mean_magnitude: if n > 0 { sum / n as f64 } else { 0.0 },
            max_magnitude: max,
            valid_fraction: n as f64 / total as f64,
        }
    }
}

/// One file of a sample: its name (relative to the dataset folder), size and SHA-256, so that
/// a rerun or `--verify` can tell a complete file from a truncated or altered one.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FileRecord {
    pub name: String,
    pub bytes: u64,
    /// Lower-case hex.
    pub sha256: String,
}

/// Everything about one sample.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SampleMeta {
    pub index: usize,
    pub seed: u64,
    pub width: usize,
    pub height: usize,
    pub channels: usize,
    /// The sample's files with their sizes and hashes (an older format listed bare names; such
    /// a sidecar no longer parses, and its sample is redone).
    pub files: Vec<FileRecord>,
    /// Present when the sample has ground-truth flow.
    pub flow: Option<FlowStats>,
    /// The source pair's name, for samples made from an existing dataset.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub source: Option<String>,
    /// Shapes and poses of every layer, for procedural scenes.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub layers: Option<Vec<LayerRecord>>,
    /// The optional knobs a chairs scene drew (photo windows, still background, tone), for
    /// configs that use them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scene_draw: Option<crate::scene::ChairsDraw>,
}

impl SampleMeta {
    /// `NNNNN_meta.json`.
    pub fn file_name(index: usize) -> String {
        format!("{index:05}_meta.json")
    }

    /// Writes the sidecar atomically; it is written last, so its presence marks completion
    /// (and its hashes say whether the files are still those it was written for).
    pub fn write(&self, path: &Path) -> Result<()> {
        io::write_bytes_atomic(path, self.to_json()?.as_bytes())
    }

    /// The sidecar's exact text.
    pub fn to_json(&self) -> Result<String> {
        serde_json::to_string(self).map_err(|e| Error::invalid("sample metadata", e.to_string()))
    }
}

/// `manifest.json`: the config, the camera stages that ran, the PSF, and every sample.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Manifest {
    pub generator: String,
    pub config: GeneratorConfig,
    pub count: usize,
    pub stages: Vec<String>,
    pub psf: String,
    pub samples: Vec<SampleMeta>,
}

impl Manifest {
    pub fn write(&self, path: &Path) -> Result<()> {
        let text = serde_json::to_string_pretty(self)
            .map_err(|e| Error::invalid("manifest", e.to_string()))?;
        io::write_bytes_atomic(path, text.as_bytes())
    }

    pub fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        serde_json::from_str(&text).map_err(|e| Error::format(path, e.to_string()))
    }
}
