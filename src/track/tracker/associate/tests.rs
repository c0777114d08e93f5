//! Tests of the association (Note S13's many objects): the gates (distance, velocity, an object's
//! size), the optimal assignment, the matching cascade, the weak detections and the merges.

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
