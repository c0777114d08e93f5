//! Many objects (Movie S2): every region above a minimum area is a detection; tracks keep
//! their IDs through optimal assignment on the distance to each track's predicted position,
//! with a gate; a track is confirmed after `confirm` consecutive hits whose motion is
//! consistent (the centre moved as the regions' motion said it would, the motion the frames
//! confirm where the alignment ran and the flow's otherwise, which a blob of spurious flow on a
//! still background does not do) and ended after `patience` consecutive
//! misses, so one missed detection does not change an ID; a track that coasts out of the frame
//! ends at once (its object has left the view). IDs are given at confirmation. When
//! two objects merge into one region, the tracks on it coast until it splits. Each track has
//! its own predictor. A track that ends is kept for a while (`reid_frames`): a new track
//! whose colour and birthplace its object could have (DeepSORT's re-identification, with the
//! region's mean colour as descriptor) takes its ID back, as does a new track on the object of
//! a confirmed track that is coasting.

use std::collections::VecDeque;

use serde::Serialize;

use super::appearance::Appearance;
use super::associate::{Association, Tracked, associate, object_gate};
use super::reid::Lost;
pub use super::tracker_config::TrackerConfig;
use crate::error::{Error, Result};
use crate::track::detect::roi::{Region, covers};
use crate::track::detect::split::Seed;
use crate::track::motion::mtp::{Estimate, Mtp};
use crate::track::motion::step::Step;
use crate::track::robust;

/// One track's estimate in one frame.
#[derive(Clone, Debug, PartialEq)]
pub struct TrackEstimate {
    pub id: usize,
    pub estimate: Estimate,
    /// True when a detection was matched this frame (false while coasting).
    pub observed: bool,
}

/// Region `d` placed at its foreground centre (`Region::foreground`) when that centre lies
/// nearer `predicted` than the flow centroid does and within `gate` × the region's equivalent
/// radius of it; `None` otherwise (or when `d` was placed, or has no such centre).
fn adopt_foreground(d: &Region, predicted: (f64, f64), gate: f64) -> Option<Region> {
    let f = d.foreground.filter(|_| d.placed.is_none())?;
    let to_f = (f.0 - predicted.0).hypot(f.1 - predicted.1);
    let to_c = (d.centroid.0 - predicted.0).hypot(d.centroid.1 - predicted.1);
    let radius = (d.pixels as f64 / std::f64::consts::PI).sqrt();
    (to_f < to_c && to_f <= gate * radius).then(|| Region {
        placed: Some(f),
        ..d.clone()
    })
}

/// The median of `values`; `None` when there are none.
fn median(values: &VecDeque<usize>) -> Option<f64> {
    let mut v: Vec<usize> = values.iter().copied().collect();
    robust::upper_median(&mut v).map(|m| m as f64)
}

use super::consistency::{Consistency, Hit, hit, per_frame};

struct Track {
    /// The reported ID (0 until confirmed).
    id: usize,
    /// An internal key, given at birth, for the debug output.
    key: usize,
    mtp: Mtp,
    /// The last `confirm` hits while the track is tentative: the region's centre (the placed
    /// one where the still background placed it), its mean flow and the motion the frames
    /// confirm (the aligned one, the mean flow where the alignment did not run).
    window: VecDeque<Hit>,
    /// The last hit's motions per stream frame (its mean flow, the motion the frames
    /// confirm): a tentative track's window bridges a miss with them.
    last_motion: ((f64, f64), (f64, f64)),
    hits: usize,
    misses: usize,
    confirmed: bool,
    /// One-frame-ahead prediction used for matching.
    predicted: (f64, f64),
    /// The filtered centre in the last frame.
    centre: (f64, f64),
    /// The areas (pixels) of the last `area_window` whole detections.
    areas: VecDeque<usize>,
    /// The object's colour, from its whole detections.
    appearance: Option<Appearance>,
    /// The frame of its first detection and that detection's centre.
    born: (usize, (f64, f64)),
    /// The last frame with a whole detection and the filtered centre then.
    last_seen: (usize, (f64, f64)),
    /// The largest motion (px/frame) of its detections: the mean flow's or the aligned one.
    top_speed: f64,
}

impl Track {
    /// Its object's radius (px): that of a disc of its whole detections' median area.
    fn radius(&self) -> Option<f64> {
        median(&self.areas).map(|a| (a / std::f64::consts::PI).sqrt())
    }

    /// Its gate before coasting widens it (`associate::object_gate`).
    fn gate(&self, config: &TrackerConfig) -> f64 {
        object_gate(self.radius(), config)
    }
}

/// What became of one detection in the last frame (for the debug output).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Assignment {
    /// The track's internal key (stable over its life, tentative or not).
    pub key: usize,
    /// The reported ID, when the track is confirmed.
    pub id: Option<usize>,
    /// `new`, `tentative`, `confirmed` (this frame), `re-identified` (confirmed this frame with
    /// the ID of a track that ended or coasted), `tracked`, `merged` (shared by several
    /// tracks, which coast), `partial` (matched, but too small a part of the object to move
    /// the track, which coasts), or `fragment` (unmatched, beside a confirmed track: no new
    /// track).
    pub state: &'static str,
}

/// A tentative track whose confirmation window is full but not yet consistent, and why.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Held {
    pub key: usize,
    pub reason: String,
}

/// The multi-object tracker.
pub struct Tracker {
    config: TrackerConfig,
    tracks: Vec<Track>,
    next_id: usize,
    next_key: usize,
    /// Per detection of the last frame.
    pub assignments: Vec<Option<Assignment>>,
    /// Tentative tracks held back from confirmation in the last frame.
    pub held: Vec<Held>,
    /// The frame's width and height (px), when known: a coasting track whose centre leaves it
    /// ends, since its object has left the view (or was never where the track went).
    frame_size: Option<(f64, f64)>,
    /// Ended tracks that may be re-identified.
    lost: Vec<Lost>,
    /// The last step's time and span: how far ahead (stream frames) the tracks' predictions
    /// look (`track::motion::step`).
    last: Option<Step>,
}

impl Tracker {
    pub fn new(config: TrackerConfig) -> Result<Self> {
        config.validate()?;
        Ok(Self {
            config,
            tracks: Vec::new(),
            next_id: 1,
            next_key: 1,
            assignments: Vec::new(),
            held: Vec::new(),
            frame_size: None,
            lost: Vec::new(),
            last: None,
        })
    }

    /// Tells the tracker the frame's size: from then on a track that coasts (no detection)
    /// with its centre outside the frame ends instead of extrapolating on.
    pub fn set_frame_size(&mut self, width: usize, height: usize) {
        self.frame_size = Some((width as f64, height as f64));
    }

    /// The confirmed tracks seen within the confirmation window, where they are expected in the
    /// next frame: the seeds of a merged region's split (`track::detect::split`).
    pub fn seeds(&self) -> Vec<Seed> {
        self.tracks
            .iter()
            .filter(|t| t.confirmed && t.misses <= self.config.confirm)
            .filter_map(|t| {
                let area = median(&t.areas)?;
                Some(Seed {
                    at: t.predicted,
                    radius: (area / std::f64::consts::PI).sqrt(),
                    velocity: t.mtp.velocity(),
                })
            })
            .collect()
    }

    /// Processes one frame's detections; returns the confirmed tracks' estimates with
    /// predictions `horizon` frames ahead.
    pub fn step(
        &mut self,
        frame: usize,
        detections: &[Region],
        horizon: usize,
    ) -> Result<Vec<TrackEstimate>> {
        self.step_at(Step::every(frame), detections, horizon)
    }

    /// `step` on a stream processed at uneven gaps (`track::motion::step`): the detections'
    /// motion is per stream frame (their flow over `step.span`, divided by it), predictions
    /// are `horizon` stream frames ahead, and the frame counts (re-identification, the lost
    /// tracks' memory) are in stream frames; confirmation and coasting count processed frames.
    pub fn step_at(
        &mut self,
        step: Step,
        detections: &[Region],
        horizon: usize,
    ) -> Result<Vec<TrackEstimate>> {
        if let Some(last) = self.last
            && step.t <= last.t
        {
            return Err(Error::invalid(
                "tracking step",
                format!("time must increase, got {} after {}", step.t, last.t),
            ));
        }
        let frame = step.frame();
        // The predictions were made this far ahead: the gates widen as for coasted frames.
        let lead = self.last.map_or(1.0, |l| step.t - l.t);
        self.last = Some(step);
        let view: Vec<Tracked> = self
            .tracks
            .iter()
            .map(|t| Tracked {
                predicted: t.predicted,
                velocity: t.mtp.velocity(),
                lead,
                misses: t.misses,
                confirmed: t.confirmed,
                appearance: t.appearance.as_ref(),
                radius: t.radius(),
            })
            .collect();
        let Association { matches, shared } = associate(&view, detections, &self.config);
        let mut used = vec![false; detections.len()];
        let mut out = Vec::new();
        let horizon = horizon.max(1);
        self.assignments = vec![None; detections.len()];
        self.held.clear();
        let confirm = self.config.confirm;
        let tolerance = Consistency {
            px: self.config.consistency_px,
            rel: self.config.consistency_rel,
            max_ratio: self.config.consistency_max_ratio,
        };
        // Where the confirmed tracks are: a tentative track there is a fragment of their object.
        let exclusion = self.config.birth_exclusion_px;
        let mut occupied: Vec<(usize, (f64, f64))> = self
            .tracks
            .iter()
            .filter(|t| t.confirmed)
            .map(|t| (t.id, t.predicted))
            .collect();
        // Tracks confirmed this frame: (index, its estimate's place in `out`, its detection),
        // given their IDs after the loop, once it is known which tracks coast.
        let mut newly: Vec<(usize, Option<usize>, Option<usize>)> = Vec::new();
        for (i, (t, m)) in self.tracks.iter_mut().zip(&matches).enumerate() {
            let det = m.and_then(|j| {
                used[j] = true;
                (!shared[j]).then(|| &detections[j])
            });
            let adopted = det.and_then(|d| {
                t.confirmed
                    .then(|| adopt_foreground(d, t.predicted, self.config.foreground_gate))
                    .flatten()
            });
            let det = adopted.as_ref().or(det);
            // Inside a merged region the object is seen, only not separately: no miss.
            let in_merge = m.is_some_and(|j| shared[j])
                || (m.is_none()
                    && detections
                        .iter()
                        .zip(&shared)
                        .any(|(d, &s)| s && covers(d, t.predicted)));
            // A region placed on the frame's foreground has its centre on the object (the
            // placement refuses a centre that moves more than half the region's radius): it
            // is not a fragment, however small against the track's earlier (smeared) regions.
            let partial = det.is_some_and(|d| {
                d.placed.is_none()
                    && median(&t.areas)
                        .is_some_and(|a| (d.pixels as f64) < self.config.partial_area_ratio * a)
            });
            let e = t.mtp.step_at(step, det.filter(|_| !partial), horizon)?;
            if let Some(d) = det.filter(|_| !partial) {
                t.last_seen = (frame, e.centroid);
                let aligned = d.aligned.map_or(0.0, |a| a.0.hypot(a.1));
                let speed = d.mean_flow.0.hypot(d.mean_flow.1).max(aligned);
                if speed.is_finite() {
                    t.top_speed = t.top_speed.max(speed);
                }
                if let Some(c) = d.colour {
                    match t.appearance.as_mut() {
                        Some(a) => a.update(c),
                        None => t.appearance = Some(Appearance::new(c)),
                    }
                }
                t.areas.push_back(d.pixels);
                while t.areas.len() > self.config.area_window.max(1) {
                    t.areas.pop_front();
                }
            }
            let was_confirmed = t.confirmed;
            if let Some(d) = det {
                t.hits += 1;
                t.misses = 0;
                if !t.confirmed {
                    t.window.push_back(hit(d, step.span));
                    t.last_motion = per_frame(d);
                    while t.window.len() > confirm {
                        t.window.pop_front();
                    }
                }
            } else if !in_merge {
                t.misses += 1;
                if !t.confirmed {
                    // The centre at the next hit lies one more step on: the last hit's motion
                    // stands in for the motion of the frame missed.
                    let ((fu, fv), (au, av)) = t.last_motion;
                    if let Some(last) = t.window.back_mut() {
                        last.1 = (last.1.0 + fu * step.span, last.1.1 + fv * step.span);
                        last.2 = (last.2.0 + au * step.span, last.2.1 + av * step.span);
                    }
                }
            }
            if !t.confirmed && t.hits >= confirm {
                let beside = occupied
                    .iter()
                    .find(|(_, c)| (c.0 - t.predicted.0).hypot(c.1 - t.predicted.1) <= exclusion);
                let verdict = match beside {
                    Some((0, _)) => Some("a fragment beside a track confirmed now".to_string()),
                    Some((id, _)) => Some(format!("a fragment beside track {id}")),
                    None => tolerance.verdict(&t.window),
                };
                match verdict {
                    None => {
                        // Its ID is given after the loop (a new one, or one re-identified).
                        occupied.push((0, t.predicted));
                        t.confirmed = true;
                        t.window.clear();
                        newly.push((i, None, *m));
                    }
                    Some(reason) if t.window.len() >= confirm => {
                        // Keep it tentative: the window slides, so an object whose first frames
                        // were poorly segmented (entering the frame) is confirmed later.
                        if det.is_some() {
                            self.held.push(Held { key: t.key, reason });
                        }
                    }
                    Some(_) => {}
                }
            }
            if let Some(j) = *m {
                self.assignments[j] = Some(Assignment {
                    key: t.key,
                    id: t.confirmed.then_some(t.id),
                    state: if shared[j] {
                        "merged"
                    } else if partial {
                        "partial"
                    } else if t.confirmed && !was_confirmed {
                        "confirmed"
                    } else if adopted.is_some() {
                        "placed by prediction"
                    } else if t.confirmed {
                        "tracked"
                    } else {
                        "tentative"
                    },
                });
            }
            t.predicted = e.next;
            t.centre = e.centroid;
            let outside = self.frame_size.is_some_and(|(w, h)| {
                let (x, y) = e.centroid;
                !(x >= 0.0 && y >= 0.0 && x <= w - 1.0 && y <= h - 1.0)
            });
            if det.is_none() && !in_merge && outside {
                // Coasted out of the view: the track ends here, unreported.
                t.misses = usize::MAX;
                continue;
            }
            if t.confirmed && t.misses <= self.config.max_coast_reported {
                if let Some(n) = newly.last_mut().filter(|n| n.0 == i) {
                    n.1 = Some(out.len());
                }
                out.push(TrackEstimate {
                    id: t.id,
                    estimate: e,
                    observed: det.is_some(),
                });
            }
        }
        // IDs taken over from coasting tracks, whose own estimates (if reported) go.
        let mut taken_over = Vec::new();
        let slots: Vec<usize> = newly.iter().filter_map(|n| n.1).collect();
        for (i, slot, j) in newly {
            let id = match self.reidentify(i, frame) {
                Some((id, coasting)) => {
                    if coasting {
                        taken_over.push(id);
                    }
                    if let Some(a) = j.and_then(|j| self.assignments[j].as_mut()) {
                        a.state = "re-identified";
                    }
                    id
                }
                None => {
                    self.next_id += 1;
                    self.next_id - 1
                }
            };
            self.tracks[i].id = id;
            if let Some(e) = slot.and_then(|s| out.get_mut(s)) {
                e.id = id;
            }
            if let Some(a) = j.and_then(|j| self.assignments[j].as_mut()) {
                a.id = Some(id);
            }
        }
        if !taken_over.is_empty() {
            let mut n = 0;
            out.retain(|e| {
                n += 1;
                slots.contains(&(n - 1)) || !taken_over.contains(&e.id)
            });
        }
        let (patience, tentative_patience) = (self.config.patience, self.config.tentative_patience);
        let ended = self
            .tracks
            .iter()
            .filter(|t| t.confirmed && t.id != 0 && t.misses > patience);
        for t in ended {
            if let Some(a) = t.appearance.clone().filter(|a| a.is_mature()) {
                self.lost.push(Lost {
                    id: t.id,
                    last_seen: t.last_seen,
                    top_speed: t.top_speed,
                    gate: t.gate(&self.config),
                    appearance: a,
                });
            }
        }
        let keep = self.config.reid_frames;
        self.lost
            .retain(|l| keep > 0 && frame.saturating_sub(l.last_seen.0) <= keep);
        self.tracks
            .retain(|t| t.misses <= patience && (t.confirmed || t.misses <= tentative_patience));
        self.births(step, detections, &used, horizon, &mut out)?;
        out.sort_by_key(|t| t.id);
        Ok(out)
    }
}

mod births;
mod reidentify;
#[cfg(test)]
mod tests;
