//! Scoring's tests (Table S5's RMSE_2D): the definition, coverage, the matching, objects
//! leaving the view, ID switches and spurious tracks.

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
    assert!(back.objects[1].horizons[0].rmse_2d.is_nan() && back.objects[1].centre_error.is_nan());
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
