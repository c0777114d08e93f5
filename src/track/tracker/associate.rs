//! Association of one frame's detections with the tracks (Note S13's many objects, Movie S2):
//! gated optimal assignment on the distance to each track's prediction (with its velocity and
//! appearance gates and the appearance cost) over the detections that passed the photometric
//! test with their flow, in DeepSORT's matching cascade (the confirmed tracks seen most
//! recently first, the tentative ones last), then the weak ones (`track::detect::retry`) for
//! the tracks left, confirmed or (`TrackerConfig::weak_continues_tentative`) tentative
//! (ByteTrack's low-score detections, which go to confirmed tracks only), a second chance by
//! distance alone for confirmed tracks still without a detection (ByteTrack's second
//! association), and the merges, regions that hide a second confirmed track's object. The two later rounds leave a
//! region that overlaps one taken in the first: it is the rest of that track's object.

use super::appearance::Appearance;
use super::hungarian::assign;
use super::tracker_config::TrackerConfig;
use crate::track::detect::roi::{Region, covers};

/// What association needs to know of one track.
pub struct Tracked<'a> {
    /// Its prediction for this frame (px).
    pub predicted: (f64, f64),
    /// Its position filter's velocity (px/frame).
    pub velocity: (f64, f64),
    /// The stream frames the prediction looked ahead (1 at the full rate): the gate widens
    /// with each frame past the first as with each coasted frame.
    pub lead: f64,
    /// Consecutive frames without a detection.
    pub misses: usize,
    pub confirmed: bool,
    /// Its object's colour, once it has one.
    pub appearance: Option<&'a Appearance>,
    /// The radius (px) of a disc of its detections' median area, once it has one.
    pub radius: Option<f64>,
}

/// One frame's association.
pub struct Association {
    /// Per track, the detection it takes.
    pub matches: Vec<Option<usize>>,
    /// Per detection, whether it hides the object of a confirmed track besides the one it was
    /// matched to (a merge: every track on it coasts).
    pub shared: Vec<bool>,
}

/// The most a track's gate may be, in radii of its object (the radius of a disc of its
/// detections' median area): `TrackerConfig::gate_px`'s 40 px are 2.7 radii of the 640×480
/// discs of radius 15 it was set on. A smaller object gets a narrower gate: on a 320×240
/// clip of five discs of radius 8, 40 px let a track that lost its disc take another 41 px
/// away (7 ID switches; 5 with the gate in radii, the 640×480 clips unchanged).
pub const GATE_RADII: f64 = 2.7;

/// Track `t`'s gate before it widens with coasting (`object_gate`).
fn gate(t: &Tracked, config: &TrackerConfig) -> f64 {
    object_gate(t.radius, config)
}

/// The gate of a track whose object has `radius` (px, when known): `gate_px`, or
/// `GATE_RADII` of the radius where that is less.
pub fn object_gate(radius: Option<f64>, config: &TrackerConfig) -> f64 {
    radius.map_or(config.gate_px, |r| config.gate_px.min(GATE_RADII * r))
}

/// Matches `detections` to `tracks` (see the module's text).
pub fn associate(tracks: &[Tracked], detections: &[Region], config: &TrackerConfig) -> Association {
    let (k, floor) = (config.appearance_k, config.appearance_floor);
    let lambda = config.appearance_px;
    let looks = |t: &Tracked, d: &Region| t.appearance.is_none_or(|a| a.admits(d.colour, k, floor));
    let exclusion = config.birth_exclusion_px;
    let cost: Vec<Vec<f64>> = tracks
        .iter()
        .map(|t| {
            let coasted = t.misses as f64 + (t.lead - 1.0).max(0.0);
            let gate = gate(t, config) * (1.0 + 0.5 * coasted).min(config.max_gate_factor);
            let v = t.velocity;
            let vgate = config.velocity_gate_px + config.velocity_gate_rel * v.0.hypot(v.1);
            detections
                .iter()
                .map(|d| {
                    let dist = ((d.centroid.0 - t.predicted.0).powi(2)
                        + (d.centroid.1 - t.predicted.1).powi(2))
                    .sqrt();
                    let dv = (d.mean_flow.0 - v.0).hypot(d.mean_flow.1 - v.1);
                    // A NaN velocity difference (unknown) does not close the gate.
                    if dist <= gate && (dv.is_nan() || dv <= vgate) && looks(t, d) {
                        dist + lambda * t.appearance.map_or(0.0, |a| a.cost(d.colour, floor))
                    } else {
                        f64::INFINITY
                    }
                })
                .collect()
        })
        .collect();
    // The weak detections wait for the tracks the others leave.
    let all: Vec<usize> = (0..tracks.len()).collect();
    let strong = only(&cost, &all, |j| !detections[j].weak);
    let mut matches = if config.match_cascade {
        cascade(tracks, &strong)
    } else {
        assign(&strong)
    };
    // A region that overlaps one a track took in the first round is a part of that track's
    // object (one object seen as a fragment beside the rest of it), not another object: the
    // later rounds, which admit weaker evidence, leave it.
    let first: Vec<usize> = matches.iter().flatten().copied().collect();
    let claimed: Vec<bool> = (0..detections.len())
        .map(|j| {
            first
                .iter()
                .any(|&k| k != j && overlaps(&detections[j], &detections[k]))
        })
        .collect();
    if detections.iter().any(|d| d.weak) {
        let rows: Vec<usize> = (0..tracks.len())
            .filter(|&i| {
                matches[i].is_none() && (tracks[i].confirmed || config.weak_continues_tentative)
            })
            .collect();
        let weak = only(&cost, &rows, |j| detections[j].weak && !claimed[j]);
        for (&i, m) in rows.iter().zip(assign(&weak)) {
            if m.is_some() {
                matches[i] = m;
            }
        }
    }
    // A second chance (as ByteTrack's second association): a confirmed track left without
    // a detection takes an unmatched one within the birth-exclusion radius of its
    // prediction, by distance alone. One bad match can throw a track's velocity off, and
    // the velocity gate would then refuse its object, which would only be called a
    // fragment of it and never move it again.
    let taken: Vec<bool> = (0..detections.len())
        .map(|j| matches.contains(&Some(j)))
        .collect();
    let orphans: Vec<usize> = (0..tracks.len())
        .filter(|&i| matches[i].is_none() && tracks[i].confirmed)
        .collect();
    if !orphans.is_empty() && taken.iter().any(|&t| !t) {
        let second: Vec<Vec<f64>> = orphans
            .iter()
            .map(|&i| {
                let track = &tracks[i];
                let p = track.predicted;
                detections
                    .iter()
                    .zip(&taken)
                    .enumerate()
                    .map(|(j, (d, &t))| {
                        let dist = (d.centroid.0 - p.0).hypot(d.centroid.1 - p.1);
                        if !t && !claimed[j] && dist <= exclusion && looks(track, d) {
                            dist
                        } else {
                            f64::INFINITY
                        }
                    })
                    .collect()
            })
            .collect();
        for (&i, m) in orphans.iter().zip(assign(&second)) {
            matches[i] = m;
        }
    }
    // A merge: a confirmed track left without a detection whose prediction lies inside a
    // detection given to another track (within that region's equivalent radius). Both
    // objects are then hidden in one region, whose centre and flow belong to neither, so
    // every track on it coasts on its own motion until the region splits again. Only a
    // track seen within the confirmation window makes one: the prediction of a track that
    // has coasted longer is an extrapolation, not evidence of a hidden object (it would
    // stop the other track and then take its object).
    let mut shared = vec![false; detections.len()];
    for (t, m) in tracks.iter().zip(&matches) {
        if m.is_some() || !t.confirmed || t.misses > config.confirm {
            continue;
        }
        for (j, d) in detections.iter().enumerate() {
            if covers(d, t.predicted) && matches.contains(&Some(j)) {
                shared[j] = true;
            }
        }
    }
    Association { matches, shared }
}

/// True when either region's centre lies within the other's equivalent radius.
fn overlaps(a: &Region, b: &Region) -> bool {
    covers(a, b.centroid) || covers(b, a.centroid)
}

/// In the cascade, a detection whose cost to a later track is under this share of its cost
/// to an earlier one waits for the later track.
const CASCADE_YIELD: f64 = 0.5;

/// The matching cascade (DeepSORT's, Wojke et al. 2017): the optimal assignment of the
/// confirmed tracks seen in the last frame first, then of those missed once on the detections
/// they left, and so on, and the tentative tracks' last. A track that has coasted longer has
/// the less certain prediction, and its gate has widened: given the same detection, a track
/// seen a frame ago keeps its object rather than lose it to one lost for several (two movers
/// that cross, one of whose flow fell short). A detection much nearer a later track than an
/// earlier one (`CASCADE_YIELD`) waits for the later track.
fn cascade(tracks: &[Tracked], cost: &[Vec<f64>]) -> Vec<Option<usize>> {
    let mut matches = vec![None; tracks.len()];
    let mut taken = vec![false; cost.first().map_or(0, Vec::len)];
    // (tentative, misses) per level: the confirmed tracks by their misses, the tentative ones
    // as one level after them.
    let level = |t: &Tracked| (!t.confirmed, if t.confirmed { t.misses } else { 0 });
    let mut levels: Vec<(bool, usize)> = tracks.iter().map(level).collect();
    levels.sort_unstable();
    levels.dedup();
    for at in levels {
        let rows: Vec<usize> = (0..tracks.len())
            .filter(|&i| level(&tracks[i]) == at)
            .collect();
        let later: Vec<usize> = (0..tracks.len())
            .filter(|&i| level(&tracks[i]) > at)
            .collect();
        let mut sub = only(cost, &rows, |j| !taken[j]);
        // Recency orders the tracks, but does not hand a track a detection that lies much
        // nearer a later track's prediction: that is the later track's object, seen again
        // after a miss, beside a neighbour whose own object went unseen this frame.
        for (r, &i) in rows.iter().enumerate() {
            for (j, c) in sub[r].iter_mut().enumerate() {
                if later
                    .iter()
                    .any(|&k| cost[k][j] < CASCADE_YIELD * cost[i][j])
                {
                    *c = f64::INFINITY;
                }
            }
        }
        for (&i, m) in rows.iter().zip(assign(&sub)) {
            if let Some(j) = m {
                taken[j] = true;
            }
            matches[i] = m;
        }
    }
    matches
}

/// The rows `rows` of `cost` with every column `keep` refuses forbidden.
fn only(cost: &[Vec<f64>], rows: &[usize], keep: impl Fn(usize) -> bool) -> Vec<Vec<f64>> {
    rows.iter()
        .map(|&i| {
            cost[i]
                .iter()
                .enumerate()
                .map(|(j, &c)| if keep(j) { c } else { f64::INFINITY })
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests;
