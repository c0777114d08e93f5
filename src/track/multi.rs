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
use super::associate::{Association, Tracked, associate, covers};
use super::mtp::{Estimate, Mtp};
use super::reid::{Candidate, Lost, reid_distance};
use super::roi::Region;
pub use super::tracker_config::TrackerConfig;
use crate::error::{Error, Result};

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
    if v.is_empty() {
        return None;
    }
    let mid = v.len() / 2;
    Some(*v.select_nth_unstable(mid).1 as f64)
}

use super::consistency::{Consistency, Hit};

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
        if !(0.0..1.0).contains(&config.partial_area_ratio) {
            return Err(Error::invalid(
                "tracker.partial_area_ratio",
                format!("must be in [0, 1), got {}", config.partial_area_ratio),
            ));
        }
        if config.consistency_max_ratio.is_nan() || config.consistency_max_ratio < 1.0 {
            return Err(Error::invalid(
                "tracker.consistency_max_ratio",
                format!("must be >= 1, got {}", config.consistency_max_ratio),
            ));
        }
        if !(config.foreground_gate.is_finite() && config.foreground_gate >= 0.0) {
            return Err(Error::invalid(
                "tracker.foreground_gate",
                format!(
                    "must be finite and >= 0 (0: off), got {}",
                    config.foreground_gate
                ),
            ));
        }
        if config.max_gate_factor.is_nan() || config.max_gate_factor < 1.0 {
            return Err(Error::invalid(
                "tracker.max_gate_factor",
                format!("must be >= 1, got {}", config.max_gate_factor),
            ));
        }
        for (n, v) in [
            ("consistency_px", config.consistency_px),
            ("consistency_rel", config.consistency_rel),
            ("velocity_gate_px", config.velocity_gate_px),
            ("velocity_gate_rel", config.velocity_gate_rel),
            ("birth_exclusion_px", config.birth_exclusion_px),
            ("appearance_k", config.appearance_k),
            ("reid_k", config.reid_k),
        ] {
            if v.is_nan() || v < 0.0 {
                return Err(Error::invalid(
                    format!("tracker.{n}"),
                    format!("must be >= 0 (inf turns the test off), got {v}"),
                ));
            }
        }
        if !(config.appearance_floor.is_finite() && config.appearance_floor > 0.0) {
            return Err(Error::invalid(
                "tracker.appearance_floor",
                format!("must be finite and > 0, got {}", config.appearance_floor),
            ));
        }
        if !(config.appearance_px.is_finite() && config.appearance_px >= 0.0) {
            return Err(Error::invalid(
                "tracker.appearance_px",
                format!("must be finite and >= 0, got {}", config.appearance_px),
            ));
        }
        Ok(Self {
            config,
            tracks: Vec::new(),
            next_id: 1,
            next_key: 1,
            assignments: Vec::new(),
            held: Vec::new(),
            frame_size: None,
            lost: Vec::new(),
        })
    }

    /// Tells the tracker the frame's size: from then on a track that coasts (no detection)
    /// with its centre outside the frame ends instead of extrapolating on.
    pub fn set_frame_size(&mut self, width: usize, height: usize) {
        self.frame_size = Some((width as f64, height as f64));
    }

    /// Processes one frame's detections; returns the confirmed tracks' estimates with
    /// predictions `horizon` frames ahead.
    pub fn step(
        &mut self,
        frame: usize,
        detections: &[Region],
        horizon: usize,
    ) -> Result<Vec<TrackEstimate>> {
        let view: Vec<Tracked> = self
            .tracks
            .iter()
            .map(|t| Tracked {
                predicted: t.predicted,
                velocity: t.mtp.velocity(),
                misses: t.misses,
                confirmed: t.confirmed,
                appearance: t.appearance.as_ref(),
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
            let e = t.mtp.step(frame, det.filter(|_| !partial), horizon)?;
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
                    t.window.push_back(hit(d));
                    while t.window.len() > confirm {
                        t.window.pop_front();
                    }
                }
            } else if !in_merge {
                t.misses += 1;
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
            t.predicted = e.path[0];
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
        let patience = self.config.patience;
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
                    appearance: a,
                });
            }
        }
        let keep = self.config.reid_frames;
        self.lost
            .retain(|l| keep > 0 && frame.saturating_sub(l.last_seen.0) <= keep);
        self.tracks
            .retain(|t| t.misses <= patience && (t.confirmed || t.misses == 0));
        for (j, d) in detections.iter().enumerate() {
            if used[j] {
                continue;
            }
            if let Some(t) = self.tracks.iter().find(|t| {
                t.confirmed
                    && (t.centre.0 - d.centroid.0).hypot(t.centre.1 - d.centroid.1) <= exclusion
            }) {
                self.assignments[j] = Some(Assignment {
                    key: t.key,
                    id: Some(t.id),
                    state: "fragment",
                });
                continue;
            }
            let mut mtp = Mtp::new(self.config.mtp.clone())?;
            let e = mtp.step(frame, Some(d), horizon)?;
            let mut t = Track {
                id: 0,
                born: (frame, d.centroid),
                last_seen: (frame, e.centroid),
                top_speed: 0.0,
                key: self.next_key,
                mtp,
                window: VecDeque::from([hit(d)]),
                hits: 1,
                misses: 0,
                confirmed: false,
                predicted: e.path[0],
                centre: e.centroid,
                areas: VecDeque::from([d.pixels]),
                appearance: d.colour.map(Appearance::new),
            };
            self.next_key += 1;
            // With a window of one frame there is nothing to compare: confirmed at once.
            if confirm <= 1 {
                t.confirmed = true;
                t.id = self.next_id;
                self.next_id += 1;
                out.push(TrackEstimate {
                    id: t.id,
                    estimate: e,
                    observed: true,
                });
            }
            self.assignments[j] = Some(Assignment {
                key: t.key,
                id: t.confirmed.then_some(t.id),
                state: "new",
            });
            self.tracks.push(t);
        }
        out.sort_by_key(|t| t.id);
        Ok(out)
    }

    /// The ID that track `i`, confirmed in `frame`, takes back: that of the ended or coasting
    /// track whose object it may be (`reid_distance`) and nearest to it in colour. A coasting
    /// track that gives up its ID ends; an ended one leaves the memory.
    fn reidentify(&mut self, i: usize, frame: usize) -> Option<(usize, bool)> {
        if self.config.reid_frames == 0 {
            return None;
        }
        let t = &self.tracks[i];
        let colour = t.appearance.as_ref().filter(|a| a.is_mature())?.mean();
        let born = t.born;
        let config = &self.config;
        let (gate, floor, k) = (config.gate_px, config.appearance_floor, config.reid_k);
        let coasting = self.tracks.iter().enumerate().filter_map(|(j, o)| {
            let c = Candidate {
                last_seen: o.last_seen,
                top_speed: o.top_speed,
                appearance: o.appearance.as_ref()?,
            };
            let fresh = o.id == 0 || j == i || !o.confirmed || o.misses == 0;
            let k = (!fresh && frame.saturating_sub(o.last_seen.0) <= config.reid_frames)
                .then(|| reid_distance(&c, born, colour, gate, floor, k))??;
            Some((k, Ok(j)))
        });
        let ended = self.lost.iter().enumerate().filter_map(|(j, l)| {
            let c = Candidate {
                last_seen: l.last_seen,
                top_speed: l.top_speed,
                appearance: &l.appearance,
            };
            Some((reid_distance(&c, born, colour, gate, floor, k)?, Err(j)))
        });
        let best = coasting.chain(ended).min_by(|a, b| a.0.total_cmp(&b.0))?;
        Some(match best.1 {
            Ok(j) => {
                let o = &mut self.tracks[j];
                let id = o.id;
                // It gives its ID up and ends (not remembered: its object is found).
                o.id = 0;
                o.misses = usize::MAX;
                (id, true)
            }
            Err(j) => (self.lost.swap_remove(j).id, false),
        })
    }
}

/// A tentative track's hit on `d`: the object's centre and motion as the frames measure them
/// (the placed centre, the aligned motion), besides the flow's mean: a flow that gives a small
/// mover a third of its motion would otherwise hold it back for as long as it is seen.
fn hit(d: &Region) -> Hit {
    (
        d.placed.unwrap_or(d.centroid),
        d.mean_flow,
        d.aligned.unwrap_or(d.mean_flow),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn det(x: f64, y: f64, vx: f64, vy: f64) -> Region {
        Region {
            colour: None,
            pixels: 40,
            centroid: (x, y),
            speed: vx.hypot(vy),
            direction: Some(vy.atan2(vx)),
            bbox: [0, 0, 1, 1],
            mean_flow: (vx, vy),
            placed: None,
            foreground: None,
            aligned: None,
        }
    }

    /// Object A (red) moves right and is missed for frames 20–23; object B (green) enters at
    /// frame 20 just beside A's predicted path, moving the same way. Without the appearance
    /// cue, A's coasting track takes B's first detection and follows B (an ID switch); with
    /// it, B starts its own track and A's ID waits for A.
    #[test]
    fn a_coasting_track_does_not_take_an_object_of_another_colour() {
        let red = |n: usize| [200.0 + (n % 3) as f64, 40.0, 40.0 - (n % 2) as f64];
        let green = |n: usize| [40.0, 190.0 + (n % 2) as f64, 60.0];
        let run = |config: TrackerConfig| {
            let mut tr = Tracker::new(config).unwrap();
            // The ID nearest A and nearest B in each frame after B entered.
            let mut on_a = Vec::new();
            let mut on_b = Vec::new();
            for n in 0..40 {
                let (ax, bx) = (20.0 + 3.0 * n as f64, 20.0 + 3.0 * n as f64 + 6.0);
                let mut dets = Vec::new();
                if !(20..24).contains(&n) {
                    dets.push(Region {
                        colour: Some(red(n)),
                        ..det(ax, 50.0, 3.0, 0.0)
                    });
                }
                if n >= 20 {
                    dets.push(Region {
                        colour: Some(green(n)),
                        ..det(bx, 62.0, 3.0, 0.0)
                    });
                }
                let out = tr.step(n, &dets, 1).unwrap();
                for t in &out {
                    let (x, y) = t.estimate.centroid;
                    if (x - ax).hypot(y - 50.0) < 4.0 {
                        on_a.push((n, t.id));
                    }
                    if n >= 20 && (x - bx).hypot(y - 62.0) < 4.0 {
                        on_b.push((n, t.id));
                    }
                }
            }
            (on_a, on_b)
        };
        let (on_a, on_b) = run(TrackerConfig::default());
        assert!(on_a.iter().all(|&(_, id)| id == 1), "A: {on_a:?}");
        assert!(on_a.iter().any(|&(n, _)| n >= 30), "A taken back: {on_a:?}");
        assert!(on_b.iter().all(|&(_, id)| id != 1), "B: {on_b:?}");
        // Without the cue A's ID follows B.
        let (_, on_b) = run(TrackerConfig {
            appearance_k: f64::INFINITY,
            appearance_px: 0.0,
            ..TrackerConfig::default()
        });
        assert!(on_b.iter().any(|&(_, id)| id == 1), "B: {on_b:?}");
    }

    /// Per frame, the IDs reported on a red object A and on a green object B (within 4 px).
    type Seen = (Vec<(usize, usize)>, Vec<(usize, usize)>);

    /// A (red, 3 px/frame to the right) is seen in frames 0–19, hidden in 20–`back` − 1 and
    /// seen again from frame `back`, `jump` px below where it went and moving by `v` px/frame
    /// (it turned behind the occluder); B (green) enters at frame 60 far away. Returns the
    /// IDs seen on each.
    fn hide_and_return(config: TrackerConfig, back: usize, jump: f64, v: (f64, f64)) -> Seen {
        let red = |n: usize| [200.0 + (n % 3) as f64, 40.0, 40.0 - (n % 2) as f64];
        let green = |n: usize| [40.0, 190.0 + (n % 2) as f64, 60.0];
        let mut tr = Tracker::new(config).unwrap();
        let (mut on_a, mut on_b) = (Vec::new(), Vec::new());
        for n in 0..back + 40 {
            let a = if n < back {
                (20.0 + 3.0 * n as f64, 50.0)
            } else {
                let k = (n - back) as f64;
                (20.0 + 3.0 * back as f64 + v.0 * k, 50.0 + jump + v.1 * k)
            };
            let va = if n < back { (3.0, 0.0) } else { v };
            let b = (300.0 - 2.0 * n as f64, 300.0);
            let mut dets = Vec::new();
            if n < 20 || n >= back {
                dets.push(Region {
                    colour: Some(red(n)),
                    ..det(a.0, a.1, va.0, va.1)
                });
            }
            if n >= 60 {
                dets.push(Region {
                    colour: Some(green(n)),
                    ..det(b.0, b.1, -2.0, 0.0)
                });
            }
            let out = tr.step(n, &dets, 1).unwrap();
            let mut ids: Vec<usize> = out.iter().map(|t| t.id).collect();
            ids.dedup();
            assert_eq!(ids.len(), out.len(), "an ID reported twice in frame {n}");
            for t in &out {
                let (x, y) = t.estimate.centroid;
                if (x - a.0).hypot(y - a.1) < 4.0 {
                    on_a.push((n, t.id));
                }
                if (x - b.0).hypot(y - b.1) < 4.0 {
                    on_b.push((n, t.id));
                }
            }
        }
        (on_a, on_b)
    }

    #[test]
    fn an_object_seen_again_takes_its_id_back_and_another_one_does_not() {
        // Hidden for 40 frames, longer than the patience: the track ended, and its ID waits.
        let (on_a, on_b) = hide_and_return(TrackerConfig::default(), 60, 20.0, (3.0, 0.0));
        assert!(on_a.iter().all(|&(_, id)| id == 1), "A: {on_a:?}");
        assert!(on_a.iter().any(|&(n, _)| n >= 70), "A seen again: {on_a:?}");
        assert!(on_b.iter().all(|&(_, id)| id == 2), "B: {on_b:?}");
        // Without re-identification A comes back as a new object.
        let off = TrackerConfig {
            reid_frames: 0,
            ..TrackerConfig::default()
        };
        let (on_a, _) = hide_and_return(off, 60, 20.0, (3.0, 0.0));
        assert!(
            on_a.iter().any(|&(n, id)| n >= 70 && id != 1),
            "A: {on_a:?}"
        );
        // Beyond the memory (150 frames), or farther than A could have gone, a new ID.
        let (on_a, _) = hide_and_return(TrackerConfig::default(), 200, 20.0, (3.0, 0.0));
        assert!(
            on_a.iter().any(|&(n, id)| n >= 200 && id != 1),
            "A: {on_a:?}"
        );
        let (on_a, _) = hide_and_return(TrackerConfig::default(), 30, 300.0, (3.0, 0.0));
        assert!(
            on_a.iter().any(|&(n, id)| n >= 40 && id != 1),
            "A: {on_a:?}"
        );
    }

    #[test]
    fn a_new_track_on_a_coasting_tracks_object_takes_its_id_and_it_ends() {
        // Hidden for 6 frames, then 45 px below its path and moving down: too far for the
        // second association and too different in motion for the gate of A's coasting track,
        // so a new track starts on A and is confirmed while A's track still coasts.
        let (on_a, _) = hide_and_return(TrackerConfig::default(), 26, 45.0, (0.0, 3.0));
        assert!(on_a.iter().all(|&(_, id)| id == 1), "A: {on_a:?}");
        assert!(on_a.iter().any(|&(n, _)| n >= 40), "A seen again: {on_a:?}");
        let off = TrackerConfig {
            reid_frames: 0,
            ..TrackerConfig::default()
        };
        let (on_a, _) = hide_and_return(off, 26, 45.0, (0.0, 3.0));
        assert!(on_a.iter().any(|&(_, id)| id != 1), "A: {on_a:?}");
        // With coasting tracks reported, the old track's estimate goes when its ID is taken.
        let (on_a, _) = hide_and_return(
            TrackerConfig {
                max_coast_reported: 15,
                ..TrackerConfig::default()
            },
            26,
            45.0,
            (0.0, 3.0),
        );
        assert!(on_a.iter().all(|&(_, id)| id == 1), "A: {on_a:?}");
    }

    /// A (red) is lost at frame 10 and its track coasts on at 3 px/frame; its prediction then
    /// runs through B (green, 1 px/frame, tracked all along) in frames 20–30. A prediction that no detection
    /// has checked for longer than the confirmation window is no hidden object: B is not
    /// declared merged (which would make it coast) and keeps being measured.
    #[test]
    fn a_long_coasting_track_does_not_stop_the_track_it_runs_into() {
        let red = [200.0, 40.0, 40.0];
        let green = [40.0, 190.0, 60.0];
        let mut tr = Tracker::new(TrackerConfig::default()).unwrap();
        let mut b_unmeasured = Vec::new();
        for n in 0..40 {
            let mut dets = vec![Region {
                colour: Some(green),
                pixels: 400,
                ..det(70.0 + n as f64, 50.0, 1.0, 0.0)
            }];
            if n < 10 {
                dets.push(Region {
                    colour: Some(red),
                    ..det(20.0 + 3.0 * n as f64, 50.0, 3.0, 0.0)
                });
            }
            let out = tr.step(n, &dets, 1).unwrap();
            for t in &out {
                if (t.estimate.centroid.0 - (70.0 + n as f64)).abs() < 4.0 && !t.observed {
                    b_unmeasured.push(n);
                }
            }
            if n >= 12 {
                let state = tr.assignments[0].as_ref().map(|a| a.state);
                assert_eq!(state, Some("tracked"), "B in frame {n}");
            }
        }
        assert!(b_unmeasured.is_empty(), "B coasted in {b_unmeasured:?}");
    }

    #[test]
    fn ids_persist_through_crossings_and_missed_frames() {
        let mut tr = Tracker::new(TrackerConfig::default()).unwrap();
        let mut ids_a = Vec::new();
        for n in 0..40 {
            let a = det(10.0 + 3.0 * n as f64, 50.0 + 0.5 * n as f64, 3.0, 0.5);
            let b = det(130.0 - 3.0 * n as f64, 70.0 - 0.5 * n as f64, -3.0, -0.5);
            // Object a is missed every 9th frame.
            let dets: Vec<Region> = if n % 9 == 4 { vec![b] } else { vec![a, b] };
            let out = tr.step(n, &dets, 5).unwrap();
            // The track nearest a's true centre, except where a and b coincide (n = 20).
            let (ax, ay) = (10.0 + 3.0 * n as f64, 50.0 + 0.5 * n as f64);
            let near =
                |t: &&TrackEstimate| (t.estimate.centroid.0 - ax).hypot(t.estimate.centroid.1 - ay);
            if let Some(t) = out.iter().min_by(|p, q| near(p).total_cmp(&near(q)))
                && near(&t) < 5.0
                && n.abs_diff(20) > 1
            {
                ids_a.push(t.id);
            }
        }
        ids_a.dedup();
        assert_eq!(ids_a.len(), 1, "object a changed ID: {ids_a:?}");
    }

    /// A missed object's track coasts unreported by default and takes its object back under
    /// the same ID; reported coasting is an option; a track that coasts out of the frame ends
    /// there instead of extrapolating outside it.
    #[test]
    fn coasting_tracks_are_unreported_and_end_at_the_frame_edge() {
        let seen = |n: usize| !(12..16).contains(&n);
        for report in [0usize, 3] {
            let mut tr = Tracker::new(TrackerConfig {
                max_coast_reported: report,
                ..TrackerConfig::default()
            })
            .unwrap();
            tr.set_frame_size(200, 100);
            let mut ids = Vec::new();
            for n in 0..30 {
                let d = det(20.0 + 3.0 * n as f64, 50.0, 3.0, 0.0);
                let dets = if seen(n) { vec![d] } else { vec![] };
                let out = tr.step(n, &dets, 1).unwrap();
                if (12..16).contains(&n) {
                    // Coasting for n − 11 frames.
                    assert_eq!(
                        out.len(),
                        usize::from(n - 11 <= report),
                        "frame {n}: {out:?}"
                    );
                    assert!(out.iter().all(|t| !t.observed));
                } else if n >= 5 {
                    assert_eq!(out.len(), 1, "frame {n}");
                    ids.push(out[0].id);
                }
            }
            ids.dedup();
            assert_eq!(ids, vec![1], "report {report}: the ID survives the gap");
        }
        // Moving left 6 px a frame from x = 40 and never seen again after frame 6: it would
        // coast to x < 0 by frame 12 and on for 15 frames; it ends there.
        let mut tr = Tracker::new(TrackerConfig {
            max_coast_reported: 30,
            ..TrackerConfig::default()
        })
        .unwrap();
        tr.set_frame_size(200, 100);
        for n in 0..25 {
            let dets = if n <= 6 {
                vec![det(76.0 - 6.0 * n as f64, 50.0, -6.0, 0.0)]
            } else {
                vec![]
            };
            let out = tr.step(n, &dets, 1).unwrap();
            for t in &out {
                assert!(t.estimate.centroid.0 >= 0.0, "frame {n}: {:?}", t.estimate);
            }
            if n >= 14 {
                assert!(out.is_empty(), "frame {n}: the track left the frame");
            }
        }
    }

    #[test]
    fn a_blob_that_does_not_move_as_its_flow_says_is_never_confirmed() {
        let mut tr = Tracker::new(TrackerConfig::default()).unwrap();
        for n in 0..30 {
            // A real mover, a blob that stays put while its flow says 3 px/frame, and a
            // fragment of the mover's region beside it.
            let mover = det(20.0 + 3.0 * n as f64, 40.0, 3.0, 0.0);
            let blob = det(150.0 + 0.3 * (n % 2) as f64, 90.0, 3.0, 0.0);
            let fragment = det(20.0 + 3.0 * n as f64 + 12.0, 52.0, 3.0, 0.0);
            let out = tr.step(n, &[mover, blob, fragment], 3).unwrap();
            assert!(out.len() <= 1, "frame {n}: {out:?}");
            if n >= 4 {
                assert_eq!(out.len(), 1, "frame {n}");
                assert!((out[0].estimate.centroid.1 - 40.0).abs() < 1.0);
                assert_eq!(out[0].id, 1);
            }
            if n >= 5 {
                assert!(tr.held.iter().any(|h| h.reason.contains("inconsistent")));
            }
        }
        for c in [
            TrackerConfig {
                consistency_px: f64::NAN,
                ..TrackerConfig::default()
            },
            TrackerConfig {
                max_gate_factor: 0.5,
                ..TrackerConfig::default()
            },
            TrackerConfig {
                consistency_max_ratio: 0.5,
                ..TrackerConfig::default()
            },
            TrackerConfig {
                partial_area_ratio: 1.5,
                ..TrackerConfig::default()
            },
        ] {
            assert!(Tracker::new(c).is_err());
        }
    }

    /// A small mover whose flow gives it a third of its motion (4 px/frame against 12): its
    /// centre moves three times as far as the flows say, so on the flow alone it is held back
    /// for as long as it is seen. The frames' alignment measures its motion, and with it the
    /// track is confirmed at the fifth hit. A still blob with the same flow, whose alignment
    /// finds no motion, stays tentative either way; a placed centre that jumps about while the
    /// flow's centroid moves smoothly holds the track back too.
    #[test]
    fn a_mover_is_confirmed_on_the_motion_the_frames_confirm() {
        let run = |aligned: bool, jitter: f64| {
            let mut tr = Tracker::new(TrackerConfig::default()).unwrap();
            let mut first = None;
            for n in 0..20 {
                let x = 30.0 + 12.0 * n as f64;
                let mover = Region {
                    aligned: aligned.then_some((12.0, 0.0)),
                    placed: Some((x, 60.0 + jitter * (n % 3) as f64)),
                    ..det(x, 60.0, 4.0, 0.0)
                };
                let blob = Region {
                    aligned: aligned.then_some((0.1, 0.0)),
                    ..det(200.0, 150.0, 4.0, 0.0)
                };
                let out = tr.step(n, &[mover, blob], 1).unwrap();
                for t in &out {
                    assert!(t.estimate.centroid.1 < 100.0, "the blob confirmed at {n}");
                }
                if first.is_none() && !out.is_empty() {
                    first = Some(n);
                }
            }
            first
        };
        assert_eq!(run(true, 0.0), Some(4));
        assert_eq!(run(false, 0.0), None);
        assert_eq!(run(true, 25.0), None);
    }

    #[test]
    fn a_fragment_of_the_object_keeps_the_track_alive_without_moving_it() {
        // An object of 400 px moving 3 px/frame along y = 50; every 4th frame from 10 on only
        // a 40 px fragment of it is found, 12 px off its centre (part of it moved in an
        // estimated flow).
        let run = |ratio: f64, placed: bool| {
            let mut tr = Tracker::new(TrackerConfig {
                partial_area_ratio: ratio,
                ..TrackerConfig::default()
            })
            .unwrap();
            let mut worst = 0.0f64;
            let mut states = Vec::new();
            for n in 0..30 {
                let x = 10.0 + 3.0 * n as f64;
                let mut d = det(x, 50.0, 3.0, 0.0);
                d.pixels = 400;
                if n >= 10 && n % 4 == 0 {
                    d = det(x + 4.0, 62.0, 3.0, 0.0);
                    // The placement, when it ran, found the object's centre from the frames.
                    d.placed = placed.then_some((x, 50.0));
                }
                let out = tr.step(n, &[d], 3).unwrap();
                states.push(tr.assignments[0].as_ref().map(|a| a.state));
                if n >= 10 {
                    assert_eq!(out.len(), 1, "frame {n}: the track lives on");
                    let c = out[0].estimate.centroid;
                    worst = worst.max((c.0 - x).hypot(c.1 - 50.0));
                }
            }
            (worst, states)
        };
        let (coasting, states) = run(0.35, false);
        let (following, _) = run(0.0, false);
        assert!(states.contains(&Some("partial")), "{states:?}");
        // A small region placed on the object is whole: it moves the track, to the right place.
        let (placed, states) = run(0.35, true);
        assert!(!states.contains(&Some("partial")), "{states:?}");
        assert!(placed < 1.0, "the track strays {placed} px from the object");
        assert!(
            coasting < 1.0,
            "the track strays {coasting} px from the object"
        );
        assert!(
            following > 3.0,
            "without the rule the fragment pulls it {following} px"
        );
    }

    #[test]
    fn a_foreground_centre_the_prediction_confirms_places_the_region() {
        // An object of 800 px (radius 16) moving 4 px/frame along y = 50. From frame 10 the
        // flow's region is smeared 14 px ahead of it (more than half its radius, so the still
        // background did not place it) while the frames' foreground centre is the object's.
        // In frames 20–24 a second foreground, another object's, lies 14 px to the side.
        let run = |gate: f64| {
            let mut tr = Tracker::new(TrackerConfig {
                foreground_gate: gate,
                ..TrackerConfig::default()
            })
            .unwrap();
            let (mut worst, mut sideways, mut adopted) = (0.0f64, 0.0f64, 0);
            for n in 0..30 {
                let x = 10.0 + 4.0 * n as f64;
                let mut d = det(x, 50.0, 4.0, 0.0);
                d.pixels = 800;
                if n >= 10 {
                    d.centroid = (x + 14.0, 50.0);
                    d.foreground = Some(if (20..25).contains(&n) {
                        (x + 14.0, 64.0)
                    } else {
                        (x + 0.5, 50.0)
                    });
                }
                let out = tr.step(n, &[d], 1).unwrap();
                let state = tr.assignments[0].as_ref().map(|a| a.state);
                adopted += usize::from(state == Some("placed by prediction"));
                if n >= 12 {
                    assert_eq!(out.len(), 1, "frame {n}");
                    let c = out[0].estimate.centroid;
                    sideways = sideways.max((c.1 - 50.0).abs());
                    if !(20..30).contains(&n) {
                        worst = worst.max((c.0 - x).hypot(c.1 - 50.0));
                    }
                }
            }
            (worst, sideways, adopted)
        };
        // Taken where the prediction confirms it (frames 10–19); the other object's centre,
        // farther from the prediction than the flow's centroid, is not (the track is not
        // pulled sideways). After five frames on the smeared centroid the prediction lies
        // nearer it than the object's centre, which is then no longer taken (frames 25–29):
        // the rule trusts the motion model only while it has been on the object.
        let (worst, sideways, adopted) = run(0.5);
        assert!(worst < 3.0, "the track strays {worst} px from the object");
        assert!(
            sideways < 1.0,
            "pulled {sideways} px towards the other object"
        );
        assert_eq!(adopted, 10, "frames placed by the prediction");
        // Off, the smeared centroid pulls the track ahead of its object.
        let (smeared, _, adopted) = run(0.0);
        assert!(smeared > 10.0, "without it the track is {smeared} px off");
        assert_eq!(adopted, 0);
        // Unit: nearer the prediction and within the gate, or not.
        let mut d = det(30.0, 50.0, 4.0, 0.0);
        d.pixels = 800;
        d.foreground = Some((17.0, 50.0));
        let at = |d: &Region, p| adopt_foreground(d, p, 0.5).and_then(|r| r.placed);
        assert_eq!(at(&d, (16.0, 50.0)), Some((17.0, 50.0)));
        assert_eq!(at(&d, (26.0, 50.0)), None, "the centroid is nearer");
        assert_eq!(at(&d, (5.0, 50.0)), None, "12 px: beyond 0.5 × 16 px");
        d.placed = Some((20.0, 50.0));
        assert_eq!(at(&d, (16.0, 50.0)), None, "already placed");
    }
}
