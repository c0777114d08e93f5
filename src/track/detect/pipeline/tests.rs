//! The detection pipeline's tests: the change test under flow jitter, the alignment, a merged
//! region split between tracks, a weak detection beside another region.

use super::*;
use crate::track::detect::still_background::PlaceConfig;
use crate::types::Image;
use rand_distr::{Distribution, StandardNormal};

/// Noisy frames of a still textured background with a textured 14×14 square moving
/// 2 px right from (30, 20); the flow is exact on the square and jitters by up to 3 px in
/// slowly turning directions on the background, as an estimated flow does on a dark
/// still scene.
fn scene(seed: u64) -> (GreyPair, Flow) {
    let (w, h) = (96, 64);
    let mut rng = crate::rng::stream(seed, &[1]);
    let mut noise = || 0.015 * Distribution::<f32>::sample(&StandardNormal, &mut rng);
    let tex = |x: f32, y: f32| 0.3 + 0.06 * (x * 0.35).sin() * (y * 0.25).cos();
    let obj = |x: f32, y: f32| 0.55 + 0.2 * (x * 1.2).sin() * (y * 0.8).cos();
    let inside =
        |x: f32, y: f32, x0: f32| (x0..x0 + 14.0).contains(&x) && (20.0..34.0).contains(&y);
    let (mut a, mut b) = (Image::zeros(1, h, w), Image::zeros(1, h, w));
    let mut flow = Flow::zeros(h, w);
    for y in 0..h {
        for x in 0..w {
            let (xf, yf) = (x as f32, y as f32);
            let va = if inside(xf, yf, 30.0) {
                obj(xf, yf)
            } else {
                tex(xf, yf)
            };
            let vb = if inside(xf, yf, 32.0) {
                obj(xf - 2.0, yf)
            } else {
                tex(xf, yf)
            };
            a.set(0, y, x, va + noise());
            b.set(0, y, x, vb + noise());
            if inside(xf, yf, 30.0) {
                flow.set(y, x, 2.0, 0.0);
            } else {
                let j = 1.5 + 1.5 * (xf * 0.21 + seed as f32).sin() * (yf * 0.17).cos();
                let angle = 3.0 * (xf * 0.09).sin() + 2.0 * (yf * 0.13 + seed as f32).cos();
                flow.set(y, x, j * angle.cos(), j * angle.sin());
            }
        }
    }
    (GreyPair::new(&a, &b).unwrap(), flow)
}

#[test]
fn a_slow_mover_under_the_flow_jitter_is_found_by_the_change_test() {
    for seed in [3, 4, 5] {
        let (pair, flow) = scene(seed);
        let cfg = DetectConfig {
            background: BackgroundModel::None,
            change: Some(true),
            ..DetectConfig::default()
        };
        let found = detect(&flow, Some(&pair), 0.5, 3.0, 20, &cfg).unwrap();
        assert!(found.change_level.is_some());
        let accepted = found.accepted();
        assert_eq!(accepted.len(), 1, "seed {seed}: {:?}", found.candidates);
        let r = &accepted[0];
        assert!(
            // Jitter next to the square that happens to move like it joins the region
            // (within the 10-px reach of the change): the centre moves a little.
            (r.centroid.0 - 36.5).abs() < 3.0 && (r.centroid.1 - 26.5).abs() < 3.0,
            "seed {seed}: centroid {:?}",
            r.centroid
        );
        assert!(
            (r.mean_flow.0 - 2.0).abs() < 0.3 && r.pixels >= 150 && r.pixels <= 300,
            "seed {seed}: {r:?}"
        );
        // Without the change test the jitter raises the threshold over the mover's 2 px.
        let off = DetectConfig {
            change: Some(false),
            ..cfg.clone()
        };
        let found = detect(&flow, Some(&pair), 0.5, 3.0, 20, &off).unwrap();
        assert!(found.threshold > 2.0 && found.change_level.is_none());
        assert!(
            found
                .accepted()
                .iter()
                .all(|r| (r.centroid.0 - 36.5).abs() > 3.0)
        );
    }
}

/// The flow gives the square 1.6 of its 2 px: with the alignment on, the accepted
/// region carries the motion the frames confirm; off (as for a given flow), none.
#[test]
fn the_alignment_gives_an_accepted_region_the_frames_motion() {
    for seed in [3, 4] {
        let (pair, mut flow) = scene(seed);
        for y in 20..34 {
            for x in 30..44 {
                flow.set(y, x, 1.6, 0.0);
            }
        }
        let cfg = DetectConfig {
            background: BackgroundModel::None,
            change: Some(true),
            align: Some(true),
            ..DetectConfig::default()
        };
        let found = detect(&flow, Some(&pair), 0.5, 3.0, 20, &cfg).unwrap();
        let accepted = found.accepted();
        assert_eq!(accepted.len(), 1, "seed {seed}: {:?}", found.candidates);
        let r = &accepted[0];
        let m = r.aligned.expect("aligned motion");
        assert!(
            (m.0 - 2.0).abs() < 0.25 && m.1.abs() < 0.25 && (r.mean_flow.0 - 1.6).abs() < 0.3,
            "seed {seed}: aligned {m:?}, mean flow {:?}",
            r.mean_flow
        );
        let off = DetectConfig {
            align: Some(false),
            ..cfg.clone()
        };
        let found = detect(&flow, Some(&pair), 0.5, 3.0, 20, &off).unwrap();
        assert!(found.accepted().iter().all(|r| r.aligned.is_none()));
    }
}

/// A `w` × `h` grey frame (0.3) with, when `with`, discs of radius 6 (0.7) at `centres`.
fn flat_discs(w: usize, h: usize, centres: &[(f64, f64)], with: bool) -> ColourFrame {
    let mut img = Image::zeros(3, h, w);
    for y in 0..h {
        for x in 0..w {
            let on = with
                && centres
                    .iter()
                    .any(|&(cx, cy)| (x as f64 - cx).hypot(y as f64 - cy) <= 6.0);
            for c in 0..3 {
                img.set(c, y, x, if on { 0.7 } else { 0.3 });
            }
        }
    }
    ColourFrame::new(&img)
}

/// A still background model that has seen 12 frames of `empty`.
fn still_model(empty: &ColourFrame) -> StillBackground {
    let mut model = StillBackground::new(PlaceConfig::default()).expect("default settings");
    for _ in 0..12 {
        model.place(empty, 0.0, &[]);
    }
    model
}

/// A region at `c` of `pixels`, moving 0.2 px right (weak: its aligned motion too).
fn blob(c: (f64, f64), pixels: usize, weak: bool) -> Region {
    Region {
        colour: None,
        weak,
        pixels,
        centroid: c,
        speed: 0.2,
        direction: Some(0.0),
        bbox: [10, 10, 46, 30],
        mean_flow: (0.2, 0.0),
        placed: None,
        foreground: None,
        aligned: weak.then_some((0.2, 0.0)),
    }
}

fn candidate(region: Region, accepted: bool, beside: bool) -> Candidate {
    Candidate {
        region,
        residuals: None,
        accepted,
        reason: "photometric".into(),
        beside,
        placement: None,
    }
}

/// One frame's detection of `candidates` on a still background.
fn detection(candidates: Vec<Candidate>) -> FrameDetection {
    FrameDetection {
        background: GlobalMotion::zero(),
        rejected_background: None,
        background_explained: true,
        threshold: 0.5,
        change_level: None,
        candidates,
    }
}

/// A region over two confirmed tracks' predictions, where the frame shows an object near
/// each, becomes two accepted parts, each placed on its object and moving as its track;
/// a rejected candidate stays as it was.
#[test]
fn a_merged_region_gives_one_part_per_track_it_hides() {
    let (w, h) = (64, 40);
    let centres = [(20.0, 20.0), (36.0, 20.0)];
    let mut model = still_model(&flat_discs(w, h, &centres, false));
    let mut found = detection(vec![
        candidate(blob((28.0, 20.0), 600, false), true, false),
        candidate(blob((55.0, 35.0), 30, false), false, false),
    ]);
    let seed = |at, v| Seed {
        at,
        radius: 7.0,
        velocity: (v, 0.0),
    };
    let seeds = [
        seed((18.0, 21.0), 1.5),
        seed((38.0, 19.0), -1.5),
        seed((5.0, 5.0), 0.0),
    ];
    found.place(&mut model, &flat_discs(w, h, &centres, true), &seeds);
    let parts = found.accepted();
    assert_eq!(parts.len(), 2, "{:?}", found.candidates);
    for ((p, want), v) in parts.iter().zip(centres).zip([1.5, -1.5]) {
        let at = p.placed.expect("placed");
        assert!((at.0 - want.0).hypot(at.1 - want.1) < 1.0, "{p:?}");
        assert_eq!((p.centroid, p.mean_flow, p.pixels), (at, (v, 0.0), 300));
    }
    assert!(matches!(
        found.candidates[0].placement,
        Some(Placement::Split { .. })
    ));
    assert_eq!(found.candidates.len(), 3);
    assert!(!found.candidates[2].accepted && found.candidates[2].region.placed.is_none());
}

/// A weak detection beside another region is accepted where the still background places it
/// on an object of its own, and stays refused where it is a piece of its neighbour's object;
/// the neighbour is placed as if it were not there.
#[test]
fn a_weak_detection_beside_another_stands_only_on_an_object_of_its_own() {
    let (w, h) = (72, 40);
    let centres = [(20.0, 20.0), (46.0, 20.0)];
    let mut model = still_model(&flat_discs(w, h, &centres, false));
    let mut found = detection(vec![
        candidate(blob((22.0, 21.0), 113, false), true, false),
        candidate(blob((43.0, 21.0), 113, true), false, true),
        candidate(blob((16.0, 20.0), 60, true), false, true),
    ]);
    found.place(&mut model, &flat_discs(w, h, &centres, true), &[]);
    let c = &found.candidates;
    assert_eq!(c.len(), 3);
    for (k, want) in [(0, centres[0]), (1, centres[1])] {
        assert!(c[k].accepted, "{:?}", c[k]);
        let at = c[k].region.placed.expect("placed");
        assert!((at.0 - want.0).hypot(at.1 - want.1) < 1.0, "{:?}", c[k]);
    }
    assert!(c[1].reason.ends_with("placed on an object of its own"));
    assert!(!c[2].accepted && c[2].region.placed.is_none());
    assert!(
        c[2].reason.contains("not placed on an object of its own"),
        "{}",
        c[2].reason
    );
    assert!(c.iter().all(|c| !c.beside));
    assert_eq!(found.accepted().len(), 2);
}

/// A region's colour is the frame's at its placed centre, or at its flow's centroid where the
/// still background kept that; a region whose foreground lies far from its centroid (a smear
/// along its object's path) has none, whatever lies under the centroid.
#[test]
fn a_region_whose_foreground_lies_far_from_its_centroid_has_no_colour() {
    let frame = flat_discs(64, 40, &[(20.0, 20.0)], true);
    let mut placed = blob((30.0, 20.0), 113, false);
    placed.placed = Some((20.0, 20.0));
    let far = Candidate {
        placement: Some(Placement::Far {
            to: (40.0, 20.0),
            shift: 20.0,
            limit: 3.0,
        }),
        ..candidate(blob((20.0, 20.0), 113, false), true, false)
    };
    let kept = Candidate {
        placement: Some(Placement::Kept("the camera moves".into())),
        ..candidate(blob((50.0, 20.0), 113, false), true, false)
    };
    let mut found = detection(vec![candidate(placed, true, false), far, kept]);
    found.colour(&frame);
    let colours: Vec<Option<[f64; 3]>> = found.candidates.iter().map(|c| c.region.colour).collect();
    // 0.7 and 0.3 of 255, rounded.
    assert_eq!(colours, vec![Some([179.0; 3]), None, Some([77.0; 3])]);
}
