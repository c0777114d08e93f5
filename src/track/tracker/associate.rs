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
mod tests {
    use super::*;

    fn det(x: f64, y: f64, flow: (f64, f64), pixels: usize) -> Region {
        Region {
            colour: None,
            weak: false,
            pixels,
            centroid: (x, y),
            speed: flow.0.hypot(flow.1),
            direction: Some(flow.1.atan2(flow.0)),
            bbox: [0, 0, 1, 1],
            mean_flow: flow,
            placed: None,
            foreground: None,
            aligned: None,
        }
    }

    fn track(predicted: (f64, f64), velocity: (f64, f64), confirmed: bool) -> Tracked<'static> {
        Tracked {
            predicted,
            velocity,
            lead: 1.0,
            misses: 0,
            confirmed,
            appearance: None,
            radius: None,
        }
    }

    /// A weak detection (`track::detect::retry`) goes to a track the others left, a tentative one
    /// only with `weak_continues_tentative`, and a track takes a detection that passed with
    /// its flow before a weak one.
    #[test]
    fn a_weak_detection_continues_a_track_the_others_left() {
        let config = TrackerConfig {
            weak_continues_tentative: false,
            ..TrackerConfig::default()
        };
        let weak = |x: f64| Region {
            weak: true,
            ..det(x, 10.0, (2.0, 0.0), 100)
        };
        let tracks = [
            track((10.0, 10.0), (2.0, 0.0), true),
            track((50.0, 10.0), (2.0, 0.0), false),
        ];
        let a = associate(&tracks, &[weak(12.0), weak(52.0)], &config);
        assert_eq!(a.matches, vec![Some(0), None]);
        // Nearer the confirmed track than the other detection, the weak one waits.
        let both = [weak(10.5), det(14.0, 10.0, (2.0, 0.0), 100)];
        assert_eq!(
            associate(&tracks[..1], &both, &config).matches,
            vec![Some(1)]
        );
        // The same detections, neither weak: the nearest.
        let plain = [det(10.5, 10.0, (2.0, 0.0), 100), both[1].clone()];
        assert_eq!(
            associate(&tracks[..1], &plain, &config).matches,
            vec![Some(0)]
        );
        // The default: the tentative track takes its weak detection too, and still prefers
        // one that passed with its flow.
        let config = TrackerConfig::default();
        let a = associate(&tracks, &[weak(12.0), weak(52.0)], &config);
        assert_eq!(a.matches, vec![Some(0), Some(1)]);
        let near = [weak(50.5), det(54.0, 10.0, (2.0, 0.0), 100)];
        assert_eq!(
            associate(&tracks[1..], &near, &config).matches,
            vec![Some(1)]
        );
    }

    /// One object seen as a small region passed with its flow and a large weak one around it:
    /// its track takes the small one, and a confirmed track that lost its own object nearby
    /// (its gate wide after coasting) does not take the large one; a weak region apart from
    /// the taken one it still takes.
    #[test]
    fn a_region_around_one_a_track_took_goes_to_no_other_track() {
        let config = TrackerConfig::default();
        let mut lost = track((40.0, 62.0), (-3.5, 1.0), true);
        lost.misses = 10;
        let tracks = [track((62.0, 50.0), (-4.0, 1.0), true), lost];
        // The fragment (radius √(58/π) ≈ 4 px) 3.5 px from the large region's centre.
        let fragment = det(62.5, 50.0, (-2.5, 1.0), 58);
        let around = Region {
            weak: true,
            ..det(59.0, 50.5, (-4.0, 1.0), 960)
        };
        let a = associate(&tracks, &[fragment.clone(), around.clone()], &config);
        assert_eq!(a.matches, vec![Some(0), None]);
        let alone = associate(&tracks[1..], &[around], &config);
        assert_eq!(
            alone.matches,
            vec![Some(0)],
            "without the fragment, the lost track's"
        );
        // A weak region 36 px from the fragment is another object: the lost track takes it.
        let apart = Region {
            weak: true,
            ..det(42.0, 80.0, (-3.5, 1.0), 300)
        };
        let a = associate(&tracks, &[fragment, apart], &config);
        assert_eq!(a.matches, vec![Some(0), Some(1)]);
    }

    #[test]
    fn a_small_objects_gate_is_narrower() {
        let config = TrackerConfig::default();
        // 35 px from the prediction: within 40 px, but beyond 2.7 radii of a disc of radius 8
        // (and beyond the second association's 30 px).
        let d = [det(135.0, 100.0, (2.0, 0.0), 200)];
        let t = |radius| Tracked {
            radius,
            ..track((100.0, 100.0), (2.0, 0.0), true)
        };
        assert_eq!(associate(&[t(None)], &d, &config).matches, vec![Some(0)]);
        assert_eq!(associate(&[t(Some(8.0))], &d, &config).matches, vec![None]);
        // A disc of radius 15 keeps the whole 40 px, and a large object no more.
        for r in [15.0, 60.0] {
            assert_eq!(associate(&[t(Some(r))], &d, &config).matches, vec![Some(0)]);
        }
        let far = [det(145.0, 100.0, (2.0, 0.0), 200)];
        assert_eq!(
            associate(&[t(Some(60.0))], &far, &config).matches,
            vec![None]
        );
    }

    #[test]
    fn the_assignment_is_optimal_and_gated_by_distance_and_velocity() {
        let config = TrackerConfig::default();
        let tracks = [
            track((10.0, 10.0), (2.0, 0.0), true),
            track((20.0, 10.0), (2.0, 0.0), true),
        ];
        // The nearest pair (track 1, detection 0: 4 px) first would leave track 0 the far
        // detection (17 px, 21 in all); the optimum pairs them in order (6 + 7 px).
        let dets = [
            det(16.0, 10.0, (2.0, 0.0), 100),
            det(27.0, 10.0, (2.0, 0.0), 100),
        ];
        let a = associate(&tracks, &dets, &config);
        assert_eq!(a.matches, vec![Some(0), Some(1)]);
        assert_eq!(a.shared, vec![false, false]);
        // Beyond the gate: no match, however alone.
        let far = [det(10.0 + 2.0 * config.gate_px, 10.0, (2.0, 0.0), 100)];
        assert_eq!(associate(&tracks[..1], &far, &config).matches, vec![None]);
        // A tentative track does not take a detection whose flow goes the other way; a
        // confirmed one takes it in the second association, within the birth exclusion.
        let against = [det(12.0, 10.0, (-6.0, 0.0), 100)];
        let tentative = [track((10.0, 10.0), (6.0, 0.0), false)];
        assert_eq!(associate(&tentative, &against, &config).matches, vec![None]);
        let confirmed = [track((10.0, 10.0), (6.0, 0.0), true)];
        assert_eq!(
            associate(&confirmed, &against, &config).matches,
            vec![Some(0)]
        );
    }

    #[test]
    fn the_cascade_keeps_a_tentative_track_from_pushing_a_confirmed_one_away() {
        let mut config = TrackerConfig::default();
        // The confirmed track's object is 10 px from it; a tentative track (a fragment's)
        // is 10 px from it too, and the only other detection is 25 px from the confirmed
        // track and out of the tentative one's gate. One assignment over both tracks matches
        // both, sending the confirmed track 25 px off.
        let tracks = [
            track((10.0, 10.0), (1.0, 0.0), true),
            track((30.0, 10.0), (1.0, 0.0), false),
        ];
        let dets = [
            det(20.0, 10.0, (1.0, 0.0), 100),
            det(-15.0, 10.0, (1.0, 0.0), 100),
        ];
        config.match_cascade = false;
        assert_eq!(
            associate(&tracks, &dets, &config).matches,
            vec![Some(1), Some(0)]
        );
        config.match_cascade = true;
        assert_eq!(
            associate(&tracks, &dets, &config).matches,
            vec![Some(0), None]
        );
        // The tentative tracks still take what the confirmed ones leave, optimally.
        let dets = [
            det(12.0, 10.0, (1.0, 0.0), 100),
            det(33.0, 10.0, (1.0, 0.0), 100),
        ];
        assert_eq!(
            associate(&tracks, &dets, &config).matches,
            vec![Some(0), Some(1)]
        );
    }

    #[test]
    fn a_track_seen_more_recently_is_matched_before_one_that_coasted() {
        // Two confirmed tracks want the one detection: the one seen in the last frame is 20 px
        // from it, the one that has coasted for four frames (its gate widened to 2 × 40 px)
        // 12 px. One assignment gives it to the nearer, the coasting one; the cascade to the
        // one seen a frame ago. Without that one, the coasting track takes it.
        let mut config = TrackerConfig::default();
        let mut lost = track((12.0, 0.0), (1.0, 0.0), true);
        lost.misses = 4;
        let seen = track((-20.0, 0.0), (1.0, 0.0), true);
        let dets = [det(0.0, 0.0, (1.0, 0.0), 100)];
        let tracks = [lost, seen];
        assert_eq!(
            associate(&tracks, &dets, &config).matches,
            vec![None, Some(0)]
        );
        config.match_cascade = false;
        assert_eq!(
            associate(&tracks, &dets, &config).matches,
            vec![Some(0), None]
        );
        config.match_cascade = true;
        assert_eq!(
            associate(&tracks[..1], &dets, &config).matches,
            vec![Some(0)]
        );
        // But a detection much nearer the track that missed a frame (3 px) than the one seen
        // last frame (35 px: its own object unseen this frame) is the missed track's.
        let mut missed = track((3.0, 0.0), (1.0, 0.0), true);
        missed.misses = 1;
        let beside = track((-35.0, 0.0), (1.0, 0.0), true);
        assert_eq!(
            associate(&[beside, missed], &dets, &config).matches,
            vec![None, Some(0)]
        );
        // Each level is optimal among its own tracks: two tracks missed once share two
        // detections by distance, after the one seen last frame took its own.
        let mut a = track((100.0, 0.0), (1.0, 0.0), true);
        let mut b = track((130.0, 0.0), (1.0, 0.0), true);
        (a.misses, b.misses) = (1, 1);
        let c = track((-50.0, 0.0), (1.0, 0.0), true);
        let dets = [
            det(128.0, 0.0, (1.0, 0.0), 100),
            det(-49.0, 0.0, (1.0, 0.0), 100),
            det(104.0, 0.0, (1.0, 0.0), 100),
        ];
        assert_eq!(
            associate(&[a, b, c], &dets, &config).matches,
            vec![Some(2), Some(0), Some(1)]
        );
    }

    #[test]
    fn a_region_over_two_confirmed_predictions_is_a_merge() {
        let config = TrackerConfig::default();
        // One region of radius √(1200/π) ≈ 19.5 px covers both predictions.
        let dets = [det(53.0, 50.0, (1.0, 0.0), 1200)];
        let tracks = [
            track((50.0, 50.0), (1.0, 0.0), true),
            track((62.0, 50.0), (1.0, 0.0), true),
        ];
        let a = associate(&tracks, &dets, &config);
        assert_eq!(a.matches, vec![Some(0), None]);
        assert_eq!(a.shared, vec![true]);
        // A track that has coasted past the confirmation window makes no merge, nor does a
        // prediction outside the region.
        let mut coasted = tracks;
        coasted[1].misses = config.confirm + 1;
        assert_eq!(associate(&coasted, &dets, &config).shared, vec![false]);
        let apart = [
            track((50.0, 50.0), (1.0, 0.0), true),
            track((80.0, 50.0), (1.0, 0.0), true),
        ];
        assert_eq!(associate(&apart, &dets, &config).shared, vec![false]);
        assert!(covers(&dets[0], (72.0, 50.0)) && !covers(&dets[0], (73.0, 50.0)));
    }
}
