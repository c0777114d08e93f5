//! Trajectory prediction error against ground truth (Note S15, Table S5): each track is
//! matched to one true object (Hungarian on the frames it covers, as IDF1 does), then for every horizon h
//! RMSE_X, RMSE_Y and RMSE_2D of the prediction made at frame n against the true centre at
//! frame n + h, over the frames where the object is wholly in view. ID switches count, for
//! each true object, how often the track covering it changes. A track the matching leaves
//! without an object is a *second track* when it lies on one object in at least half of its
//! observed frames (that object picked up again under a new ID, as MOT's fragmentations),
//! and *follows no object* otherwise (a false track). How much of each object the tracks
//! cover, and IDF1 over the same matching, are `track::eval::coverage`.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::coverage::{Coverage, coverage};
use crate::error::{Error, Result};
use crate::io::json::nan_if_null;
use crate::scene::truth::Truth;
use crate::track::detect::static_flow::BackgroundFlow;
use crate::track::tracker::hungarian::assign;
use crate::track::tracker::tracks::Tracks;

/// Errors at one horizon.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HorizonError {
    pub horizon: usize,
    /// Predictions scored.
    pub count: usize,
    /// NaN (`null` in JSON) over no predictions.
    #[serde(deserialize_with = "nan_if_null")]
    pub rmse_x: f64,
    #[serde(deserialize_with = "nan_if_null")]
    pub rmse_y: f64,
    #[serde(deserialize_with = "nan_if_null")]
    pub rmse_2d: f64,
}

/// One track's errors.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ObjectReport {
    pub id: usize,
    /// The true object it follows, or null for a track the matching leaves without one.
    pub truth_index: Option<usize>,
    /// For a track without `truth_index`: the object it lies on in at least half of its
    /// observed frames, which another track follows (a second ID on it); null for a track
    /// that follows no object. Its errors are scored against that object, but not pooled.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub second_on: Option<usize>,
    pub frames: usize,
    /// Mean distance between the tracked and the true centre (px; NaN, `null` in JSON, where
    /// the track never lies on a wholly visible object).
    #[serde(deserialize_with = "nan_if_null")]
    pub centre_error: f64,
    pub horizons: Vec<HorizonError>,
}

/// `pins track eval`'s report.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrackReport {
    pub objects: Vec<ObjectReport>,
    /// All matched tracks pooled (second tracks are not).
    pub overall: Vec<HorizonError>,
    /// True objects seen in some frame but followed by no track.
    pub missed: Vec<usize>,
    pub id_switches: usize,
    pub ms_per_frame: Option<f64>,
    /// The background-flow magnitude of the flows tracked (from `tracks.json`, or measured
    /// from the flows by `pins track eval --flows`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub background_flow: Option<BackgroundFlow>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub coverage: Option<Coverage>,
}

impl TrackReport {
    /// Tracks that follow no object: false tracks.
    pub fn false_tracks(&self) -> usize {
        self.objects
            .iter()
            .filter(|o| o.truth_index.is_none() && o.second_on.is_none())
            .count()
    }

    /// Tracks on an object that another track follows (it was picked up again under a new
    /// ID, or followed twice).
    pub fn second_tracks(&self) -> usize {
        self.objects
            .iter()
            .filter(|o| o.second_on.is_some())
            .count()
    }
}

#[derive(Default, Clone, Copy)]
struct Acc {
    n: usize,
    sx: f64,
    sy: f64,
}

impl Acc {
    fn add(&mut self, dx: f64, dy: f64) {
        self.n += 1;
        self.sx += dx * dx;
        self.sy += dy * dy;
    }

    fn error(&self, horizon: usize) -> HorizonError {
        let n = self.n.max(1) as f64;
        let nan_if_empty = |v: f64| if self.n == 0 { f64::NAN } else { v };
        HorizonError {
            horizon,
            count: self.n,
            rmse_x: nan_if_empty((self.sx / n).sqrt()),
            rmse_y: nan_if_empty((self.sy / n).sqrt()),
            rmse_2d: nan_if_empty(((self.sx + self.sy) / n).sqrt()),
        }
    }
}

/// The horizons present in `tracks`, ascending.
fn horizons(tracks: &Tracks) -> Result<Vec<usize>> {
    let mut hs = std::collections::BTreeSet::new();
    for o in &tracks.objects {
        for f in &o.frames {
            for k in f.predicted.keys() {
                let h: usize = k.parse().map_err(|_| {
                    Error::invalid("tracks", format!("horizon key {k:?} is not a frame count"))
                })?;
                hs.insert(h);
            }
        }
    }
    Ok(hs.into_iter().collect())
}

/// Scores `tracks` against `truth`.
pub fn evaluate(tracks: &Tracks, truth: &Truth) -> Result<TrackReport> {
    truth.validate()?;
    let hs = horizons(tracks)?;
    let centre = |i: usize, n: usize| -> Option<[f64; 2]> {
        let o = &truth.objects[i];
        (n < truth.frames && o.visible[n]).then(|| o.centroids[n])
    };
    // Where an object is in the frame at all (partly, as it enters or leaves the view).
    let (w, h) = (truth.width as f64, truth.height as f64);
    let present = |i: usize, n: usize| -> Option<[f64; 2]> {
        let o = &truth.objects[i];
        let c = *o.centroids.get(n)?;
        let r = o.radius;
        (c[0] + r >= 0.0 && c[1] + r >= 0.0 && c[0] - r <= w && c[1] - r <= h).then_some(c)
    };
    let dist = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]);
    // Per track and object, minus the observed frames with the track's centre within the
    // object's radius of the object's (infinite for none), counting the frames where the
    // object is at `at`.
    let hits = |at: &dyn Fn(usize, usize) -> Option<[f64; 2]>| -> Vec<Vec<f64>> {
        tracks
            .objects
            .iter()
            .map(|t| {
                (0..truth.objects.len())
                    .map(|i| {
                        let reach = truth.objects[i].radius.max(5.0);
                        let hits = t
                            .frames
                            .iter()
                            .filter(|f| f.observed)
                            .filter(|f| {
                                at(i, f.frame).is_some_and(|c| dist(f.centroid, c) <= reach)
                            })
                            .count();
                        if hits > 0 {
                            -(hits as f64)
                        } else {
                            f64::INFINITY
                        }
                    })
                    .collect()
            })
            .collect()
    };
    // Tracks are matched to objects globally, as IDF1 does: each track to the object it
    // covers in the most frames wholly in view.
    let cost = hits(&centre);
    // A track left without an object lies on one if it does in half its frames, counting
    // those where the object is partly in view: a track on an object leaving the frame
    // follows it, though its errors are scored only where the object is wholly in view.
    let on = hits(&present);
    // IDF1's matching maximises the hits: a pair without hits is worth as little as no pair
    // (cost 0, dropped after), so a long track is not moved off its object to let a short
    // one be matched too (a forbidden pair would make the assignment maximise the pairs).
    let neutral: Vec<Vec<f64>> = cost
        .iter()
        .map(|row| {
            row.iter()
                .map(|&c| if c.is_finite() { c } else { 0.0 })
                .collect()
        })
        .collect();
    let matched: Vec<Option<usize>> = assign(&neutral)
        .into_iter()
        .zip(&cost)
        .map(|(m, row)| m.filter(|&i| row[i].is_finite()))
        .collect();
    let mut overall: BTreeMap<usize, Acc> = hs.iter().map(|&h| (h, Acc::default())).collect();
    let mut objects = Vec::new();
    for ((t, m), row) in tracks.objects.iter().zip(&matched).zip(&on) {
        // A track left without an object: on the object it covers most, if that is at
        // least half of its observed frames.
        let observed = t.frames.iter().filter(|f| f.observed).count();
        let second_on = match m {
            Some(_) => None,
            None => row
                .iter()
                .enumerate()
                .filter(|(_, c)| c.is_finite())
                .min_by(|a, b| a.1.total_cmp(b.1))
                .filter(|(_, c)| 2.0 * -**c >= observed as f64)
                .map(|(i, _)| i),
        };
        let pooled = m.is_some();
        let mut acc: BTreeMap<usize, Acc> = hs.iter().map(|&h| (h, Acc::default())).collect();
        let mut centre_sum = (0.0, 0usize);
        if let Some(i) = m.or(second_on) {
            for f in &t.frames {
                if let (true, Some(c)) = (f.observed, centre(i, f.frame)) {
                    centre_sum.0 += dist(f.centroid, c);
                    centre_sum.1 += 1;
                }
                for (k, p) in &f.predicted {
                    let h: usize = k.parse().unwrap_or(0);
                    if let Some(c) = centre(i, f.frame + h) {
                        let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
                        if let Some(a) = acc.get_mut(&h) {
                            a.add(dx, dy);
                        }
                        if let Some(a) = overall.get_mut(&h).filter(|_| pooled) {
                            a.add(dx, dy);
                        }
                    }
                }
            }
        }
        objects.push(ObjectReport {
            id: t.id,
            truth_index: *m,
            second_on,
            frames: t.frames.len(),
            centre_error: if centre_sum.1 > 0 {
                centre_sum.0 / centre_sum.1 as f64
            } else {
                f64::NAN
            },
            horizons: acc.iter().map(|(&h, a)| a.error(h)).collect(),
        });
    }
    let followed: Vec<usize> = matched.iter().flatten().copied().collect();
    let missed = (0..truth.objects.len())
        .filter(|i| !followed.contains(i) && truth.objects[*i].visible.iter().any(|&v| v))
        .collect();
    let (id_switches, tracked) = clear_mot(tracks, truth);
    // Every observed track frame is a prediction. Frame N − 1 has no flow to a next frame,
    // so tracks have no record there, unless these tracks do.
    let (predictions, last) = tracks
        .objects
        .iter()
        .flat_map(|t| &t.frames)
        .filter(|f| f.observed)
        .fold((0, 0), |(n, last), f| (n + 1, last.max(f.frame + 1)));
    let span = last.clamp(truth.frames.saturating_sub(1), truth.frames);
    // IDTP: the hits of the matched pairs.
    let idtp: f64 = matched
        .iter()
        .zip(&cost)
        .filter_map(|(m, row)| m.map(|i| -row[i]))
        .sum();
    Ok(TrackReport {
        objects,
        overall: overall.iter().map(|(&h, a)| a.error(h)).collect(),
        missed,
        id_switches,
        ms_per_frame: tracks.ms_per_frame,
        background_flow: tracks.background_flow.clone(),
        coverage: Some(coverage(truth, span, &tracked, idtp, predictions)),
    })
}

/// ID switches as CLEAR MOT counts them: in every frame, true objects and observed tracks are
/// matched one to one (centre within the object's radius), keeping last frame's pairs that
/// still hold; an object matched to a different track than at its last match is a switch.
/// Also each object's frames with a match (its tracked frames).
fn clear_mot(tracks: &Tracks, truth: &Truth) -> (usize, Vec<usize>) {
    let mut by_frame: BTreeMap<usize, Vec<(usize, [f64; 2])>> = BTreeMap::new();
    for t in &tracks.objects {
        for f in t.frames.iter().filter(|f| f.observed) {
            by_frame
                .entry(f.frame)
                .or_default()
                .push((t.id, f.centroid));
        }
    }
    let objects = &truth.objects;
    let mut last: Vec<Option<usize>> = vec![None; objects.len()];
    let mut switches = 0;
    let mut tracked = vec![0usize; objects.len()];
    for n in 0..truth.frames {
        let Some(dets) = by_frame.get(&n) else {
            continue;
        };
        let d = |i: usize, j: usize| {
            let (c, p) = (objects[i].centroids[n], dets[j].1);
            let dist = (p[0] - c[0]).hypot(p[1] - c[1]);
            if objects[i].visible[n] && dist <= objects[i].radius.max(5.0) {
                dist
            } else {
                f64::INFINITY
            }
        };
        let mut now: Vec<Option<usize>> = vec![None; objects.len()];
        let mut taken = vec![false; dets.len()];
        // Pairs from the last match that still hold are kept.
        for i in 0..objects.len() {
            if let Some(j) = last[i].and_then(|id| dets.iter().position(|x| x.0 == id))
                && d(i, j).is_finite()
                && !taken[j]
            {
                now[i] = Some(j);
                taken[j] = true;
            }
        }
        let free: Vec<usize> = (0..objects.len()).filter(|&i| now[i].is_none()).collect();
        let cost: Vec<Vec<f64>> = free
            .iter()
            .map(|&i| {
                (0..dets.len())
                    .map(|j| if taken[j] { f64::INFINITY } else { d(i, j) })
                    .collect()
            })
            .collect();
        for (&i, m) in free.iter().zip(assign(&cost)) {
            if let Some(j) = m.filter(|&j| d(i, j).is_finite() && !taken[j]) {
                now[i] = Some(j);
            }
        }
        for i in 0..objects.len() {
            if let Some(j) = now[i] {
                let id = dets[j].0;
                if last[i].is_some_and(|l| l != id) {
                    switches += 1;
                }
                last[i] = Some(id);
                tracked[i] += 1;
            }
        }
    }
    (switches, tracked)
}

/// The report as a text table (Table S5 layout, with a count column).
pub fn table(report: &TrackReport) -> String {
    let mut s = format!(
        "{:<10} {:>7} {:>6} {:>10} {:>10} {:>10}\n",
        "track", "horizon", "count", "RMSE_X", "RMSE_Y", "RMSE_2D"
    );
    let mut row = |name: &str, e: &HorizonError| {
        s += &format!(
            "{:<10} {:>7} {:>6} {:>10.2} {:>10.2} {:>10.2}\n",
            name, e.horizon, e.count, e.rmse_x, e.rmse_y, e.rmse_2d
        );
    };
    for o in &report.objects {
        let name = match (o.truth_index, o.second_on) {
            (Some(i), _) => format!("ID {} ({i})", o.id),
            (None, Some(i)) => format!("ID {} ({i}')", o.id),
            (None, None) => format!("ID {} (-)", o.id),
        };
        for e in &o.horizons {
            row(&name, e);
        }
    }
    for e in &report.overall {
        row("all", e);
    }
    s += &format!(
        "ID switches {}, missed objects {:?}",
        report.id_switches, report.missed
    );
    if let Some(ms) = report.ms_per_frame {
        s += &format!(", {ms:.2} ms per frame");
    }
    s += &format!(
        ", {} tracks, {} following no object, {} second tracks on an object",
        report.objects.len(),
        report.false_tracks(),
        report.second_tracks()
    );
    if let Some(c) = &report.coverage {
        s += &format!(
            "\ncoverage {:.1} % of object frames; mostly tracked {}, partially {}, mostly lost {}; IDF1 {:.3}",
            100.0 * c.recall,
            c.mostly_tracked,
            c.partially_tracked,
            c.mostly_lost,
            c.idf1
        );
    }
    if let Some(b) = &report.background_flow {
        s += &format!(
            "\nbackground flow over static pixels: mean {:.3} px, p99 {:.3} px, max {:.2} px ({} frames)",
            b.mean, b.p99, b.max, b.frames
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::truth::TruthObject;
    use crate::track::tracker::tracks::{FrameRecord, ObjectTrack};

    fn truth() -> Truth {
        let line = |y: f64| TruthObject {
            index: 0,
            radius: 5.0,
            centroids: (0..20).map(|n| [10.0 + 2.0 * n as f64, y]).collect(),
            visible: vec![true; 20],
        };
        Truth {
            width: 100,
            height: 100,
            fps: 30.0,
            frames: 20,
            objects: vec![
                line(20.0),
                TruthObject {
                    index: 1,
                    ..line(60.0)
                },
            ],
        }
    }

    fn track(id: usize, y: f64, bias: f64) -> ObjectTrack {
        ObjectTrack {
            id,
            frames: (0..20)
                .map(|n| {
                    let x = 10.0 + 2.0 * n as f64;
                    FrameRecord {
                        frame: n,
                        centroid: [x, y],
                        speed: 2.0,
                        direction: Some(0.0),
                        observed: true,
                        predicted: [("1".to_string(), [x + 2.0 + bias, y - bias])]
                            .into_iter()
                            .collect(),
                        path: Vec::new(),
                    }
                })
                .collect(),
        }
    }

    #[test]
    fn rmse_matches_the_definition_and_tracks_match_objects() {
        let tracks = Tracks {
            objects: vec![track(7, 60.0, 3.0), track(9, 20.0, 0.0)],
            ms_per_frame: Some(1.0),
            background_flow: None,
        };
        let r = evaluate(&tracks, &truth()).unwrap();
        assert_eq!(r.objects[0].truth_index, Some(1));
        assert_eq!(r.objects[1].truth_index, Some(0));
        let e = &r.objects[0].horizons[0];
        // 19 predictions (the last one targets frame 20, past the clip), each off by (3, −3).
        assert_eq!(e.count, 19);
        assert!((e.rmse_x - 3.0).abs() < 1e-12 && (e.rmse_y - 3.0).abs() < 1e-12);
        assert!((e.rmse_2d - 18f64.sqrt()).abs() < 1e-12);
        assert_eq!(r.objects[1].horizons[0].rmse_2d, 0.0);
        assert!((r.overall[0].rmse_2d - 9f64.sqrt()).abs() < 1e-12);
        assert_eq!((r.id_switches, r.missed.len()), (0, 0));
        // Both objects followed by one track each, in every frame: IDF1 1.
        let c = r.coverage.unwrap();
        assert_eq!((c.mostly_tracked, c.recall, c.idf1), (2, 1.0, 1.0));
    }

    /// Over a clip's 19 frames with a flow (records 0..=18), an object tracked in 5 is
    /// partially tracked, one tracked in 2 mostly lost; recall and IDF1 follow by hand.
    #[test]
    fn coverage_counts_the_frames_a_track_lies_on_an_object() {
        let mut a = track(1, 20.0, 0.0);
        a.frames.truncate(5);
        let mut b = track(2, 60.0, 0.0);
        b.frames.truncate(2);
        // A third track lies 30 px off object 1 for 4 frames: no hit.
        let mut off = track(3, 90.0, 0.0);
        off.frames.truncate(4);
        let r = evaluate(
            &Tracks {
                objects: vec![a, b, off],
                ms_per_frame: None,
                background_flow: None,
            },
            &truth(),
        )
        .unwrap();
        let c = r.coverage.unwrap();
        assert_eq!(
            c.objects.iter().map(|o| o.tracked).collect::<Vec<_>>(),
            vec![5, 2]
        );
        assert_eq!(
            (c.mostly_tracked, c.partially_tracked, c.mostly_lost),
            (0, 1, 1)
        );
        assert!((c.recall - 7.0 / 38.0).abs() < 1e-12);
        assert!((c.idf1 - 14.0 / (38.0 + 11.0)).abs() < 1e-12, "{}", c.idf1);
    }

    /// Track A follows object 0 for 16 frames, then object 1 for 4; track B follows object
    /// 0 in those last 4. The most hits (16) match A to object 0 and leave B a second track
    /// on it; matching both tracks (A to object 1, B to object 0: 8 hits) would score A's
    /// whole life against the object it followed least.
    #[test]
    fn the_matching_maximises_hits_not_pairs() {
        let mut a = track(1, 20.0, 0.0);
        for f in &mut a.frames[16..] {
            f.centroid[1] = 60.0;
        }
        let mut b = track(2, 20.0, 0.0);
        b.frames.drain(..16);
        let r = evaluate(
            &Tracks {
                objects: vec![a, b],
                ms_per_frame: None,
                background_flow: None,
            },
            &truth(),
        )
        .unwrap();
        assert_eq!(r.objects[0].truth_index, Some(0));
        assert_eq!(r.objects[1].truth_index, None);
        assert_eq!(r.objects[1].second_on, Some(0));
        // IDF1: 2 · 16 hits over the objects' 40 frames and the tracks' 24.
        let idf1 = r.coverage.map_or(f64::NAN, |c| c.idf1);
        assert!((idf1 - 32.0 / 64.0).abs() < 1e-12, "{idf1}");
    }

    /// An object leaves the frame at the right (radius 5, wholly in view up to frame 3, partly
    /// up to 6). A follows it while it is wholly in view; B picks it up as it leaves, on the
    /// part still in view: B follows the object (a second track on it), not nothing, and
    /// has no error, since no frame of it is scored. The report reads back from its JSON,
    /// NaN (`null`) and all.
    #[test]
    fn a_track_on_an_object_leaving_the_view_follows_it() {
        let x = |n: usize| 80.0 + 4.0 * n as f64;
        let truth = Truth {
            width: 100,
            height: 100,
            fps: 30.0,
            frames: 20,
            objects: vec![TruthObject {
                index: 0,
                radius: 5.0,
                centroids: (0..20).map(|n| [x(n), 50.0]).collect(),
                visible: (0..20).map(|n| x(n) + 5.0 <= 100.0).collect(),
            }],
        };
        let on = |id: usize, frames: std::ops::Range<usize>| ObjectTrack {
            id,
            frames: track(id, 50.0, 0.0)
                .frames
                .into_iter()
                .filter(|f| frames.contains(&f.frame))
                .map(|f| FrameRecord {
                    centroid: [x(f.frame).min(99.0), 50.0],
                    ..f
                })
                .collect(),
        };
        let tracks = Tracks {
            objects: vec![on(1, 0..4), on(2, 4..7)],
            ms_per_frame: None,
            background_flow: None,
        };
        let r = evaluate(&tracks, &truth).unwrap();
        assert_eq!(r.objects[0].truth_index, Some(0));
        assert_eq!(
            (r.objects[1].truth_index, r.objects[1].second_on),
            (None, Some(0))
        );
        assert_eq!((r.false_tracks(), r.second_tracks()), (0, 1));
        // Frames 4–6: the object is only partly in view, so nothing of B is scored.
        assert!(r.objects[1].centre_error.is_nan());
        assert_eq!(r.objects[1].horizons[0].count, 0);
        // A track far from it still follows nothing.
        let far = Tracks {
            objects: vec![on(1, 0..4), track(3, 10.0, 0.0)],
            ms_per_frame: None,
            background_flow: None,
        };
        assert_eq!(evaluate(&far, &truth).unwrap().false_tracks(), 1);
        // The JSON round trip keeps the NaNs.
        let text = serde_json::to_string(&r).unwrap();
        assert!(text.contains("null"), "{text}");
        let back: TrackReport = serde_json::from_str(&text).unwrap();
        assert!(
            back.objects[1].horizons[0].rmse_2d.is_nan() && back.objects[1].centre_error.is_nan()
        );
        assert_eq!(back.objects[0], r.objects[0]);
    }

    #[test]
    fn a_swapped_id_counts_as_a_switch_and_a_far_track_as_spurious() {
        let mut a = track(1, 20.0, 0.0);
        let mut b = track(2, 60.0, 0.0);
        // Halfway through, the two tracks exchange objects.
        for n in 10..20 {
            std::mem::swap(&mut a.frames[n].centroid, &mut b.frames[n].centroid);
        }
        let short = ObjectTrack {
            id: 4,
            frames: track(4, 20.0, 0.0).frames[..2].to_vec(),
        };
        let far = ObjectTrack {
            id: 3,
            frames: track(3, 95.0, 0.0).frames,
        };
        let r = evaluate(
            &Tracks {
                objects: vec![a, b, far, short],
                ms_per_frame: None,
                background_flow: None,
            },
            &truth(),
        )
        .unwrap();
        // Each object passes from one track to the other once; the short track, on object 0
        // in frames 0 and 1 beside A, is not a switch.
        assert_eq!(r.id_switches, 2);
        assert!(r.objects[0].truth_index.is_some() && r.objects[1].truth_index.is_some());
        assert_eq!(r.objects[3].truth_index, None);
        assert_eq!(r.objects[2].truth_index, None);
        assert!(r.objects[2].horizons[0].rmse_2d.is_nan());
        // The short track lies on object 0, which A and B follow: a second track, scored
        // against it but not pooled; the far one follows nothing.
        assert_eq!(r.objects[3].second_on, Some(0));
        assert_eq!(r.objects[3].horizons[0].count, 2);
        assert_eq!(r.objects[2].second_on, None);
        assert_eq!((r.false_tracks(), r.second_tracks()), (1, 1));
        let matched: usize = r.objects[..2].iter().map(|o| o.horizons[0].count).sum();
        assert_eq!(r.overall[0].count, matched);
        // Coverage: these tracks have a record for every one of the 20 frames; A and B cover
        // both objects in all of them; the far track covers nothing. IDF1: each of A and B
        // lies on its matched object in 10 of its 20 frames; the short track's 2 and the far
        // track's 20 observed frames are predictions too: 2 · 20 / (40 + 62).
        let c = r.coverage.as_ref().expect("coverage");
        assert_eq!(
            c.objects
                .iter()
                .map(|o| (o.in_view, o.tracked))
                .collect::<Vec<_>>(),
            vec![(20, 20), (20, 20)]
        );
        assert_eq!(
            (c.mostly_tracked, c.partially_tracked, c.mostly_lost),
            (2, 0, 0)
        );
        assert!((c.recall - 1.0).abs() < 1e-12);
        assert!((c.idf1 - 40.0 / 102.0).abs() < 1e-12, "{}", c.idf1);
        let text = table(&r);
        assert!(text.contains("ID 4 (0')"), "{text}");
        assert!(text.contains("IDF1 0.392"), "{text}");
        assert!(
            text.contains("1 following no object, 1 second tracks on an object"),
            "{text}"
        );
    }
}
