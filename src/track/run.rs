//! Tracking a sequence of flow maps into `tracks.json`: regions per frame, the multi-object
//! tracker, and each object's predictions at the requested horizons.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::multi::{Tracker, TrackerConfig};
use super::roi::regions;
use crate::error::{Error, Result};
use crate::io;
use crate::types::Flow;

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
}

impl Tracks {
    /// Reads a `tracks.json`.
    pub fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        serde_json::from_str(&text).map_err(|e| Error::format(path, e.to_string()))
    }
}

/// Options of a run.
#[derive(Clone, Debug)]
pub struct TrackOptions {
    pub tracker: TrackerConfig,
    pub horizons: Vec<usize>,
    /// Flow magnitude (px/frame) above which a pixel moves.
    pub threshold: f64,
    /// The threshold also rises to the frame's median magnitude plus this many robust standard
    /// deviations (1.4826 × MAD), so the background jitter of an estimated flow is not motion;
    /// on an exact flow of a still background this changes nothing. 0 turns it off.
    pub noise_k: f64,
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
    track_sequence(
        files
            .iter()
            .map(|f| Ok((f.display().to_string(), io::read_flow(f)?))),
        opts,
    )
}

/// Tracks a sequence of named flows (frame n → n + 1, in order).
pub fn track_sequence(
    flows: impl Iterator<Item = Result<(String, Flow)>>,
    opts: &TrackOptions,
) -> Result<Tracks> {
    if opts.horizons.is_empty() || opts.horizons.iter().any(|&h| h == 0 || h > 10_000) {
        return Err(Error::invalid("--horizons", "need horizons in 1..=10000"));
    }
    if !(opts.threshold.is_finite() && opts.threshold >= 0.0) {
        return Err(Error::invalid(
            "--threshold",
            format!(
                "must be a finite number >= 0 (px/frame), got {}",
                opts.threshold
            ),
        ));
    }
    if !(opts.noise_k.is_finite() && opts.noise_k >= 0.0) {
        return Err(Error::invalid(
            "--noise-k",
            format!("must be a finite number >= 0, got {}", opts.noise_k),
        ));
    }
    let max_h = *opts.horizons.iter().max().unwrap_or(&1);
    let mut tracker = Tracker::new(opts.tracker.clone())?;
    let mut objects: BTreeMap<usize, Vec<FrameRecord>> = BTreeMap::new();
    let mut size: Option<(usize, usize)> = None;
    let mut busy = std::time::Duration::ZERO;
    let mut count = 0usize;
    for (frame, item) in flows.enumerate() {
        let (name, flow) = item?;
        let started = std::time::Instant::now();
        let s = (flow.height(), flow.width());
        if let Some(first) = size
            && first != s
        {
            return Err(Error::shape(
                format!("flow {name}"),
                format!("{}x{} (the first flow)", first.1, first.0),
                format!("{}x{}", s.1, s.0),
            ));
        }
        size = Some(s);
        let threshold = opts.threshold.max(noise_floor(&flow, opts.noise_k));
        let dets = regions(&flow, threshold, opts.min_area)
            .map_err(|e| Error::invalid(format!("flow {name}"), e.to_string()))?;
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
                path: e.path.iter().map(|p| [p.0, p.1]).collect(),
            });
        }
        busy += started.elapsed();
        count += 1;
    }
    Ok(Tracks {
        ms_per_frame: Some(busy.as_secs_f64() * 1e3 / count.max(1) as f64),
        objects: objects
            .into_iter()
            .map(|(id, frames)| ObjectTrack { id, frames })
            .collect(),
    })
}

/// Median flow magnitude plus `k` robust standard deviations (1.4826 × the median absolute
/// deviation); 0 when `k` is 0. Unknown (non-finite) vectors are skipped, as in the region
/// finder.
pub fn noise_floor(flow: &Flow, k: f64) -> f64 {
    if k <= 0.0 {
        return 0.0;
    }
    let mut m: Vec<f32> = flow
        .u()
        .iter()
        .zip(flow.v())
        .map(|(a, b)| a.hypot(*b))
        .filter(|v| v.is_finite())
        .collect();
    if m.is_empty() {
        return 0.0;
    }
    let mid = m.len() / 2;
    let median = *m.select_nth_unstable_by(mid, f32::total_cmp).1;
    m.iter_mut().for_each(|v| *v = (*v - median).abs());
    let mad = *m.select_nth_unstable_by(mid, f32::total_cmp).1;
    (median + k as f32 * 1.4826 * mad) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_noise_floor_ignores_a_few_movers_and_rises_with_jitter() {
        let mut f = Flow::zeros(20, 20);
        for i in 0..40 {
            f.set(i / 20, i % 20, 5.0, 0.0);
        }
        assert_eq!(
            noise_floor(&f, 3.0),
            0.0,
            "exact flow of a still background"
        );
        let mut noisy = Flow::zeros(20, 20);
        for y in 0..20 {
            for x in 0..20 {
                noisy.set(y, x, 1.0 + 0.5 * ((x * 7 + y * 3) % 5) as f32 / 4.0, 0.0);
            }
        }
        let t = noise_floor(&noisy, 3.0);
        assert!(t > 1.5 && t < 3.5, "{t}");
        assert_eq!(noise_floor(&noisy, 0.0), 0.0);
    }
}
