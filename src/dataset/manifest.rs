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

/// Everything about one sample.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SampleMeta {
    pub index: usize,
    pub seed: u64,
    pub width: usize,
    pub height: usize,
    pub channels: usize,
    /// The sample's files, relative to the dataset folder.
    pub files: Vec<String>,
    /// Present when the sample has ground-truth flow.
    pub flow: Option<FlowStats>,
    /// The source pair's name, for samples made from an existing dataset.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub source: Option<String>,
    /// Shapes and poses of every layer, for procedural scenes.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub layers: Option<Vec<LayerRecord>>,
}

impl SampleMeta {
    /// `NNNNN_meta.json`.
    pub fn file_name(index: usize) -> String {
        format!("{index:05}_meta.json")
    }

    /// Writes the sidecar atomically; it is written last, so its presence marks completion.
    pub fn write(&self, path: &Path) -> Result<()> {
        let text = serde_json::to_string(self)
            .map_err(|e| Error::invalid("sample metadata", e.to_string()))?;
        io::write_bytes_atomic(path, text.as_bytes())
    }

    /// The sidecar at `path` if it parses and every file it lists exists in `dir`.
    pub fn read_complete(path: &Path, dir: &Path) -> Option<SampleMeta> {
        let text = std::fs::read_to_string(path).ok()?;
        let meta: SampleMeta = serde_json::from_str(&text).ok()?;
        meta.files
            .iter()
            .all(|f| dir.join(f).is_file())
            .then_some(meta)
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
