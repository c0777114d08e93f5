//! Tracking a sequence of flow maps into `tracks.json`: regions per frame, the multi-object
//! tracker, and each object's predictions at the requested horizons.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Serialize;

use super::multi::{Tracker, TrackerConfig};
use super::roi::regions;
use crate::error::{Error, Result};
use crate::io;

/// One object in one frame, as written to `tracks.json`.
#[derive(Clone, Debug, Serialize)]
pub struct FrameRecord {
    pub frame: usize,
    pub centroid: [f64; 2],
    pub speed: f64,
    /// Radians; null while the object is still.
    pub direction: Option<f64>,
    pub observed: bool,
    /// Horizon (frames, as a string key) → predicted centroid.
    pub predicted: BTreeMap<String, [f64; 2]>,
}

/// One object's track.
#[derive(Clone, Debug, Serialize)]
pub struct ObjectTrack {
    pub id: usize,
    pub frames: Vec<FrameRecord>,
}

/// `tracks.json`.
#[derive(Clone, Debug, Serialize)]
pub struct Tracks {
    pub objects: Vec<ObjectTrack>,
}

/// Options of a run.
#[derive(Clone, Debug)]
pub struct TrackOptions {
    pub tracker: TrackerConfig,
    pub horizons: Vec<usize>,
    /// Flow magnitude (px/frame) above which a pixel moves.
    pub threshold: f64,
    pub min_area: usize,
}

/// The `.flo` files of a folder, sorted by name.
pub fn flow_files(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| Error::io(dir, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("flo")))
        .collect();
    v.sort();
    if v.is_empty() {
        return Err(Error::invalid(
            "--flows",
            format!("{} holds no .flo files", dir.display()),
        ));
    }
    Ok(v)
}

/// Tracks a folder of flows.
pub fn track_flows(files: &[PathBuf], opts: &TrackOptions) -> Result<Tracks> {
    if opts.horizons.is_empty() || opts.horizons.iter().any(|&h| h == 0 || h > 10_000) {
        return Err(Error::invalid("--horizons", "need horizons in 1..=10000"));
    }
    let max_h = *opts.horizons.iter().max().unwrap_or(&1);
    let mut tracker = Tracker::new(opts.tracker.clone())?;
    let mut objects: BTreeMap<usize, Vec<FrameRecord>> = BTreeMap::new();
    let mut size: Option<(usize, usize)> = None;
    for (frame, f) in files.iter().enumerate() {
        let flow = io::read_flow(f)?;
        let s = (flow.height(), flow.width());
        if let Some(first) = size
            && first != s
        {
            return Err(Error::shape(
                format!("flow {}", f.display()),
                format!("{}x{} (the first flow)", first.1, first.0),
                format!("{}x{}", s.1, s.0),
            ));
        }
        size = Some(s);
        let dets = regions(&flow, opts.threshold, opts.min_area)
            .map_err(|e| Error::invalid(format!("flow {}", f.display()), e.to_string()))?;
        for t in tracker.step(frame, &dets, max_h)? {
            let e = &t.estimate;
            let predicted = opts
                .horizons
                .iter()
                .map(|&h| (h.to_string(), [e.path[h - 1].0, e.path[h - 1].1]))
                .collect();
            objects.entry(t.id).or_default().push(FrameRecord {
                frame,
                centroid: [e.centroid.0, e.centroid.1],
                speed: e.speed,
                direction: e.direction,
                observed: t.observed,
                predicted,
            });
        }
    }
    Ok(Tracks {
        objects: objects
            .into_iter()
            .map(|(id, frames)| ObjectTrack { id, frames })
            .collect(),
    })
}
