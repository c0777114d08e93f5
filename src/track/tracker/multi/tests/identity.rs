//! The tracker's identity tests (DeepSORT's appearance cue and re-identification): an object
//! hidden and seen again keeps its ID, and another object does not take it.

use super::*;

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
/// (it turned behind the occluder), its colour unmeasured in the first `blind` frames
/// back; B (green) enters at frame 60 far away. Returns the IDs seen on each.
fn hide_and_return(
    config: TrackerConfig,
    back: usize,
    jump: f64,
    v: (f64, f64),
    blind: usize,
) -> Seen {
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
                colour: (n < back || n >= back + blind).then(|| red(n)),
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
    let (on_a, on_b) = hide_and_return(TrackerConfig::default(), 60, 20.0, (3.0, 0.0), 0);
    assert!(on_a.iter().all(|&(_, id)| id == 1), "A: {on_a:?}");
    assert!(on_a.iter().any(|&(n, _)| n >= 70), "A seen again: {on_a:?}");
    assert!(on_b.iter().all(|&(_, id)| id == 2), "B: {on_b:?}");
    // Without re-identification A comes back as a new object.
    let off = TrackerConfig {
        reid_frames: 0,
        ..TrackerConfig::default()
    };
    let (on_a, _) = hide_and_return(off, 60, 20.0, (3.0, 0.0), 0);
    assert!(
        on_a.iter().any(|&(n, id)| n >= 70 && id != 1),
        "A: {on_a:?}"
    );
    // Beyond the memory (150 frames), or farther than A could have gone, a new ID.
    let (on_a, _) = hide_and_return(TrackerConfig::default(), 200, 20.0, (3.0, 0.0), 0);
    assert!(
        on_a.iter().any(|&(n, id)| n >= 200 && id != 1),
        "A: {on_a:?}"
    );
    let (on_a, _) = hide_and_return(TrackerConfig::default(), 30, 300.0, (3.0, 0.0), 0);
    assert!(
        on_a.iter().any(|&(n, id)| n >= 40 && id != 1),
        "A: {on_a:?}"
    );
}

#[test]
fn a_new_track_on_a_coasting_tracks_object_takes_its_id_and_it_ends() {
    // Hidden for 10 frames, then 35 px below its path and moving down: too far for the
    // second association (30 px) and too different in motion for the gate of A's coasting
    // track, so a new track starts on A and is confirmed while A's track still coasts. It is
    // 48 px from where A was last seen 11 frames before, within the reach of A's gate (9.6 px:
    // 2.7 radii of its 3.6 px) and 1.25 × 3 px for each frame.
    let (on_a, _) = hide_and_return(TrackerConfig::default(), 30, 35.0, (0.0, 3.0), 0);
    assert!(on_a.iter().all(|&(_, id)| id == 1), "A: {on_a:?}");
    assert!(on_a.iter().any(|&(n, _)| n >= 40), "A seen again: {on_a:?}");
    // 45 px below, 56 px from where it was last seen: beyond that reach, a new object.
    let (on_a, _) = hide_and_return(TrackerConfig::default(), 30, 45.0, (0.0, 3.0), 0);
    assert!(
        on_a.iter().any(|&(n, id)| n >= 40 && id != 1),
        "A: {on_a:?}"
    );
    let off = TrackerConfig {
        reid_frames: 0,
        ..TrackerConfig::default()
    };
    let (on_a, _) = hide_and_return(off, 30, 35.0, (0.0, 3.0), 0);
    assert!(on_a.iter().any(|&(_, id)| id != 1), "A: {on_a:?}");
    // With coasting tracks reported, the old track's estimate goes when its ID is taken.
    let (on_a, _) = hide_and_return(
        TrackerConfig {
            max_coast_reported: 15,
            ..TrackerConfig::default()
        },
        30,
        35.0,
        (0.0, 3.0),
        0,
    );
    assert!(on_a.iter().all(|&(_, id)| id == 1), "A: {on_a:?}");
}

#[test]
fn a_track_confirmed_with_few_colours_still_takes_its_id_back() {
    // Back after 40 frames with its colour unmeasured in its first two frames (regions too
    // small or partial for a colour): confirmed on five hits with three colours, it is
    // still compared with the ended track, whose own colours are many.
    let (on_a, _) = hide_and_return(TrackerConfig::default(), 60, 20.0, (3.0, 0.0), 2);
    assert!(on_a.iter().all(|&(_, id)| id == 1), "A: {on_a:?}");
    assert!(on_a.iter().any(|&(n, _)| n >= 70), "A seen again: {on_a:?}");
    // With no colour at all it cannot be compared: a new ID.
    let (on_a, _) = hide_and_return(TrackerConfig::default(), 60, 20.0, (3.0, 0.0), 40);
    assert!(
        on_a.iter().any(|&(n, id)| n >= 70 && id != 1),
        "A: {on_a:?}"
    );
}

/// Two objects of nearly one colour: A (3 px/frame to the right along y = 20) is seen in
/// frames 0–29 and then not again (it left); B (2 px/frame to the left along y = 100) is
/// seen in frames 0–39, hidden in 40–59 and seen again from frame 60 where it went, its
/// colour then measured a little off (lighting), nearer A's than its own. Both old tracks
/// could have got to B's new track in their colour; B's, 42 px away after 21 frames, is
/// likelier than A's, 108 px away after 31 (the two-disc 320×240 clip's ID switch).
#[test]
fn a_returning_object_takes_the_id_of_the_track_that_could_reach_it_more_easily() {
    let a_colour = |n: usize| [200.0 + (n % 3) as f64, 40.0, 40.0 - (n % 2) as f64];
    let b_colour = |n: usize| [204.0 + (n % 3) as f64, 40.0, 40.0 - (n % 2) as f64];
    let mut tr = Tracker::new(TrackerConfig::default()).unwrap();
    let mut on_b = Vec::new();
    for n in 0..90 {
        let a = (20.0 + 3.0 * n as f64, 20.0);
        let b = (300.0 - 2.0 * n as f64, 100.0);
        let mut dets = Vec::new();
        if n < 30 {
            dets.push(Region {
                colour: Some(a_colour(n)),
                ..det(a.0, a.1, 3.0, 0.0)
            });
        }
        if !(40..60).contains(&n) {
            let colour = if n < 40 {
                b_colour(n)
            } else {
                [201.0, 40.0, 40.0]
            };
            dets.push(Region {
                colour: Some(colour),
                ..det(b.0, b.1, -2.0, 0.0)
            });
        }
        let out = tr.step(n, &dets, 1).unwrap();
        for t in &out {
            let (x, y) = t.estimate.centroid;
            if (x - b.0).hypot(y - b.1) < 4.0 {
                on_b.push((n, t.id));
            }
        }
    }
    let first = on_b.first().map(|&(_, id)| id);
    assert!(on_b.iter().all(|&(_, id)| Some(id) == first), "B: {on_b:?}");
    assert!(on_b.iter().any(|&(n, _)| n >= 70), "B seen again: {on_b:?}");
}
