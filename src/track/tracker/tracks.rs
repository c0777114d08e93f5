//! The tracker's output, `tracks.json` (Notes S13–S15): per object its ID and, per frame, its
//! centre, speed and direction, whether a region was matched, and its predictions at the
//! requested horizons; the run's time per frame and background-flow magnitude. The sequence
//! runner (`track::run`) writes it, the scoring (`track::eval`) and the plots read it.

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::track::detect::static_flow::BackgroundFlow;

/// One object in one frame, as written to `tracks.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct FrameRecord {
    pub frame: usize,
    pub centroid: [f64; 2],
    pub speed: f64,
    /// Radians; null while the object is still.
    pub direction: Option<f64>,
    pub observed: bool,
    /// Horizon (frames, as a string key) → predicted centroid.
    pub predicted: BTreeMap<String, [f64; 2]>,
    /// The whole predicted path, frames n + 1 … n + K (kept in memory for plots, not written).
    #[serde(skip)]
    pub path: Vec<[f64; 2]>,
}

/// One object's track.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ObjectTrack {
    pub id: usize,
    pub frames: Vec<FrameRecord>,
}

/// `tracks.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Tracks {
    pub objects: Vec<ObjectTrack>,
    /// Wall time of detection, filtering and prediction per frame (flow estimation excluded).
    #[serde(default)]
    pub ms_per_frame: Option<f64>,
    /// The background-flow magnitude of the flows tracked, when a truth was given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub background_flow: Option<BackgroundFlow>,
}

impl Tracks {
    /// Reads a `tracks.json`.
    pub fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        serde_json::from_str(&text).map_err(|e| Error::format(path, e.to_string()))
    }
}
