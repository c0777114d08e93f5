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
mod tests;
