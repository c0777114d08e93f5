//! Many objects (Movie S2): every region above a minimum area is a detection; tracks keep
//! their IDs through optimal assignment on the distance to each track's predicted position,
//! with a gate; a track is confirmed after `confirm` consecutive hits and ended after `patience`
//! consecutive misses, so one missed detection does not change an ID. When two objects merge
//! into one region, the tracks on it coast until it splits. Each track has its own predictor.

use serde::{Deserialize, Serialize};

use super::hungarian::assign;
use super::mtp::{Estimate, Mtp, MtpConfig};
use super::roi::Region;
use crate::error::{Error, Result};

/// Tracker settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrackerConfig {
    pub mtp: MtpConfig,
    /// Largest distance (px) between a prediction and a detection that may be matched; it
    /// widens by half for every frame a track has coasted, so a track re-acquires its object
    /// after an occlusion or a merge.
    pub gate_px: f64,
    /// Hits before a new track is reported.
    pub confirm: usize,
    /// Misses before a track ends.
    pub patience: usize,
}

impl Default for TrackerConfig {
    fn default() -> Self {
        Self {
            mtp: MtpConfig::default(),
            gate_px: 40.0,
            confirm: 2,
            patience: 15,
        }
    }
}

/// One track's estimate in one frame.
#[derive(Clone, Debug, PartialEq)]
pub struct TrackEstimate {
    pub id: usize,
    pub estimate: Estimate,
    /// True when a detection was matched this frame (false while coasting).
    pub observed: bool,
}

struct Track {
    id: usize,
    mtp: Mtp,
    hits: usize,
    misses: usize,
    confirmed: bool,
    /// One-frame-ahead prediction used for matching.
    predicted: (f64, f64),
}

/// The multi-object tracker.
pub struct Tracker {
    config: TrackerConfig,
    tracks: Vec<Track>,
    next_id: usize,
}

impl Tracker {
    pub fn new(config: TrackerConfig) -> Result<Self> {
        config.mtp.validate()?;
        if !(config.gate_px.is_finite() && config.gate_px > 0.0) || config.confirm == 0 {
            return Err(Error::invalid(
                "tracker",
                "gate must be finite and > 0, confirm >= 1",
            ));
        }
        Ok(Self {
            config,
            tracks: Vec::new(),
            next_id: 1,
        })
    }

    /// Processes one frame's detections; returns the confirmed tracks' estimates with
    /// predictions `horizon` frames ahead.
    pub fn step(
        &mut self,
        frame: usize,
        detections: &[Region],
        horizon: usize,
    ) -> Result<Vec<TrackEstimate>> {
        let cost: Vec<Vec<f64>> = self
            .tracks
            .iter()
            .map(|t| {
                let gate = self.config.gate_px * (1.0 + 0.5 * t.misses as f64);
                detections
                    .iter()
                    .map(|d| {
                        let dist = ((d.centroid.0 - t.predicted.0).powi(2)
                            + (d.centroid.1 - t.predicted.1).powi(2))
                        .sqrt();
                        if dist <= gate { dist } else { f64::INFINITY }
                    })
                    .collect()
            })
            .collect();
        let matches = assign(&cost);
        // A merge: a confirmed track left without a detection whose prediction lies inside a
        // detection given to another track (within that region's equivalent radius). Both
        // objects are then hidden in one region, whose centre and flow belong to neither, so
        // every track on it coasts on its own motion until the region splits again.
        let mut shared = vec![false; detections.len()];
        for (t, m) in self.tracks.iter().zip(&matches) {
            if m.is_some() || !t.confirmed {
                continue;
            }
            for (j, d) in detections.iter().enumerate() {
                if covers(d, t.predicted) && matches.contains(&Some(j)) {
                    shared[j] = true;
                }
            }
        }
        let mut used = vec![false; detections.len()];
        let mut out = Vec::new();
        let horizon = horizon.max(1);
        for (t, m) in self.tracks.iter_mut().zip(&matches) {
            let det = m.and_then(|j| {
                used[j] = true;
                (!shared[j]).then(|| &detections[j])
            });
            // Inside a merged region the object is seen, only not separately: no miss.
            let in_merge = m.is_some_and(|j| shared[j])
                || (m.is_none()
                    && detections
                        .iter()
                        .zip(&shared)
                        .any(|(d, &s)| s && covers(d, t.predicted)));
            let e = t.mtp.step(frame, det, horizon)?;
            if det.is_some() {
                t.hits += 1;
                t.misses = 0;
            } else if !in_merge {
                t.misses += 1;
            }
            t.confirmed |= t.hits >= self.config.confirm;
            t.predicted = e.path[0];
            if t.confirmed {
                out.push(TrackEstimate {
                    id: t.id,
                    estimate: e,
                    observed: det.is_some(),
                });
            }
        }
        let patience = self.config.patience;
        self.tracks
            .retain(|t| t.misses <= patience && (t.confirmed || t.misses == 0));
        for (j, d) in detections.iter().enumerate() {
            if used[j] {
                continue;
            }
            let mut mtp = Mtp::new(self.config.mtp.clone())?;
            let e = mtp.step(frame, Some(d), horizon)?;
            let mut t = Track {
                id: 0,
                mtp,
                hits: 1,
                misses: 0,
                confirmed: self.config.confirm <= 1,
                predicted: e.path[0],
            };
            // IDs go to tracks when they are born, so they stay small and in order of appearance.
            t.id = self.next_id;
            self.next_id += 1;
            if t.confirmed {
                out.push(TrackEstimate {
                    id: t.id,
                    estimate: e,
                    observed: true,
                });
            }
            self.tracks.push(t);
        }
        out.sort_by_key(|t| t.id);
        Ok(out)
    }
}

/// True when `point` lies within the equivalent radius √(area/π) of region `d`.
fn covers(d: &Region, point: (f64, f64)) -> bool {
    (d.centroid.0 - point.0).hypot(d.centroid.1 - point.1)
        <= (d.pixels as f64 / std::f64::consts::PI).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn det(x: f64, y: f64, vx: f64) -> Region {
        Region {
            pixels: 40,
            centroid: (x, y),
            speed: vx.abs(),
            direction: Some(if vx >= 0.0 { 0.0 } else { std::f64::consts::PI }),
            bbox: [0, 0, 1, 1],
        }
    }

    #[test]
    fn ids_persist_through_crossings_and_missed_frames() {
        let mut tr = Tracker::new(TrackerConfig::default()).unwrap();
        let mut ids_a = Vec::new();
        for n in 0..40 {
            let a = det(10.0 + 3.0 * n as f64, 50.0 + 0.5 * n as f64, 3.0);
            let b = det(130.0 - 3.0 * n as f64, 70.0 - 0.5 * n as f64, -3.0);
            // Object a is missed every 9th frame.
            let dets: Vec<Region> = if n % 9 == 4 { vec![b] } else { vec![a, b] };
            let out = tr.step(n, &dets, 5).unwrap();
            if let Some(t) = out.iter().find(|t| {
                t.estimate.centroid.0 < 200.0
                    && (t.estimate.centroid.1 - (50.0 + 0.5 * n as f64)).abs() < 5.0
            }) {
                ids_a.push(t.id);
            }
        }
        ids_a.dedup();
        assert_eq!(ids_a.len(), 1, "object a changed ID: {ids_a:?}");
    }
}
