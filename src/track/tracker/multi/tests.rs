//! The tracker's tests (Note S13's many objects, Movie S2): IDs through misses, crossings,
//! merges and re-identification; confirmation; the appearance cue; placement by prediction.

use super::*;

fn det(x: f64, y: f64, vx: f64, vy: f64) -> Region {
    Region {
        colour: None,
        weak: false,
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

/// Weak detections (`track::detect::retry`) alone start no track; after a track is confirmed on
/// detections that passed with their flow, weak ones carry it on under its ID.
#[test]
fn weak_detections_continue_a_track_but_start_none() {
    let at = |n: usize| det(20.0 + 3.0 * n as f64, 50.0, 3.0, 0.0);
    let weak = |n: usize| Region {
        weak: true,
        ..at(n)
    };
    let mut tr = Tracker::new(TrackerConfig::default()).unwrap();
    for n in 0..20 {
        assert!(tr.step(n, &[weak(n)], 1).unwrap().is_empty(), "frame {n}");
    }
    let mut tr = Tracker::new(TrackerConfig::default()).unwrap();
    let mut ids = Vec::new();
    for n in 0..30 {
        let d = if n < 10 { at(n) } else { weak(n) };
        for t in tr.step(n, &[d], 1).unwrap() {
            assert!(t.observed, "frame {n}: the weak detection is the track's");
            ids.push((n, t.id));
        }
    }
    let first = ids.first().map(|i| i.0);
    assert!(first.is_some_and(|f| f < 10), "{ids:?}");
    assert!(ids.iter().all(|i| i.1 == ids[0].1), "{ids:?}");
    assert_eq!(ids.last().map(|i| i.0), Some(29), "{ids:?}");
}

/// An object whose flow passes the photometric test only every third frame (a disc textured
/// like its background), the frames confirming its motion in between (weak detections): its
/// tentative tracks, started by the detections that passed with their flow, are carried on by
/// the weak ones and confirmed; with weak detections for confirmed tracks only, each
/// tentative track dies at its first weak frame and the object is never reported.
#[test]
fn weak_detections_carry_a_tentative_track_to_its_confirmation() {
    let at = |n: usize| {
        let d = det(20.0 + 3.0 * n as f64, 50.0, 3.0, 0.0);
        Region {
            weak: !n.is_multiple_of(3),
            ..d
        }
    };
    let run = |weak_continues_tentative: bool| {
        let mut tr = Tracker::new(TrackerConfig {
            weak_continues_tentative,
            ..TrackerConfig::default()
        })
        .unwrap();
        let mut ids = std::collections::BTreeSet::new();
        let mut reported = 0;
        for n in 0..30 {
            for t in tr.step(n, &[at(n)], 1).unwrap() {
                ids.insert(t.id);
                reported += 1;
            }
        }
        (ids.len(), reported)
    };
    let (tracks, reported) = run(true);
    assert_eq!(tracks, 1);
    assert!(reported >= 24, "reported on {reported} frames");
    assert_eq!(run(false), (0, 0));
}
