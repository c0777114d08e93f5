//! How much of the true objects the tracks cover, as MOTChallenge reports it (Li et al.
//! 2009; Milan et al. 2016): per object, the share of its frames in view on which some track
//! lies on it, and the objects mostly tracked (≥ 80 %), partially tracked or mostly lost
//! (< 20 %); and how well the IDs hold, IDF1 (Ristani et al. 2016): 2 IDTP over the object
//! frames plus the observed track frames.

use serde::{Deserialize, Serialize};

use crate::scene::truth::Truth;

/// One true object's coverage.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ObjectCoverage {
    pub index: usize,
    /// Frames with a flow to the next (0..N − 1, or 0..N where the tracks have a record for
    /// frame N − 1) in which the object is in view ...
    pub in_view: usize,
    /// ... and those on which an observed track lies on it (centre within its radius, CLEAR
    /// MOT's one-to-one matching), whatever its ID.
    pub tracked: usize,
}

/// How much of the objects the tracks cover and how well their IDs hold.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Coverage {
    pub objects: Vec<ObjectCoverage>,
    /// Objects tracked in at least 80 % of their frames in view, in 20–80 %, in under 20 %
    /// (MOTChallenge's MT, PT, ML); objects never in view are left out.
    pub mostly_tracked: usize,
    pub partially_tracked: usize,
    pub mostly_lost: usize,
    /// Tracked object frames over object frames in view.
    #[serde(deserialize_with = "crate::io::json::nan_if_null")]
    pub recall: f64,
    /// 2 IDTP / (object frames in view + observed track frames), IDTP being the frames on
    /// which a track lies on the object the global matching gave it.
    #[serde(deserialize_with = "crate::io::json::nan_if_null")]
    pub idf1: f64,
}

/// The coverage of each object over frames 0..`span` from its tracked frames (`clear_mot`;
/// an object without an entry has none),
/// and IDF1 from the matched pairs' hits (`idtp`) and the observed track frames
/// (`predictions`).
pub fn coverage(
    truth: &Truth,
    span: usize,
    tracked: &[usize],
    idtp: f64,
    predictions: usize,
) -> Coverage {
    let objects: Vec<ObjectCoverage> = truth
        .objects
        .iter()
        .enumerate()
        .map(|(i, o)| ObjectCoverage {
            index: i,
            in_view: o.visible.iter().take(span).filter(|&&v| v).count(),
            tracked: tracked.get(i).copied().unwrap_or(0),
        })
        .collect();
    let seen: Vec<f64> = objects
        .iter()
        .filter(|o| o.in_view > 0)
        .map(|o| o.tracked as f64 / o.in_view as f64)
        .collect();
    let in_view: usize = objects.iter().map(|o| o.in_view).sum();
    let tracked: usize = objects.iter().map(|o| o.tracked).sum();
    let ratio = |a: f64, b: usize| if b > 0 { a / b as f64 } else { f64::NAN };
    Coverage {
        mostly_tracked: seen.iter().filter(|&&r| r >= 0.8).count(),
        partially_tracked: seen.iter().filter(|&&r| (0.2..0.8).contains(&r)).count(),
        mostly_lost: seen.iter().filter(|&&r| r < 0.2).count(),
        recall: ratio(tracked as f64, in_view),
        idf1: ratio(2.0 * idtp, in_view + predictions),
        objects,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::truth::TruthObject;

    /// Three objects in a 10-frame clip: one in view in all 9 frames with a flow and tracked
    /// in 8, one in view in 5 and tracked in 2, one never in view.
    #[test]
    fn shares_classes_and_idf1_by_hand() {
        let object = |index: usize, shown: usize| TruthObject {
            index,
            radius: 5.0,
            centroids: vec![[0.0, 0.0]; 10],
            visible: (0..10).map(|n| n < shown).collect(),
        };
        let truth = Truth {
            width: 64,
            height: 64,
            fps: 30.0,
            frames: 10,
            objects: vec![object(0, 10), object(1, 5), object(2, 0)],
        };
        let c = coverage(&truth, 9, &[8, 2, 0], 9.0, 12);
        let in_view: Vec<usize> = c.objects.iter().map(|o| o.in_view).collect();
        assert_eq!(in_view, vec![9, 5, 0]);
        // 8/9 ≥ 0.8: mostly tracked; 2/5 partially; the object never in view is not counted.
        assert_eq!(
            (c.mostly_tracked, c.partially_tracked, c.mostly_lost),
            (1, 1, 0)
        );
        assert!((c.recall - 10.0 / 14.0).abs() < 1e-12);
        assert!((c.idf1 - 18.0 / 26.0).abs() < 1e-12);
        // With frame 9 recorded as well, the first object has 10 frames in view.
        assert_eq!(
            coverage(&truth, 10, &[8, 2, 0], 9.0, 12).objects[0].in_view,
            10
        );
        // No object in view and no track: the shares are undefined, not zero.
        let empty = Truth {
            objects: vec![object(0, 0)],
            ..truth
        };
        let c = coverage(&empty, 9, &[0], 0.0, 0);
        assert!(c.recall.is_nan() && c.idf1.is_nan());
    }
}
