//! The still background's placement beside other movers: two discs passing each other, crowds of
//! regions, merged regions split, pending regions.

use super::*;

/// Two discs of radius 8 passing each other at 1.5 px a frame, one right along `y1` and one
/// left along `y2`, both at x = 48 in frame `n`: the model (with `cfg`) after frames 0 … n − 1,
/// frame n and the two centres in it.
fn passing(
    cfg: PlaceConfig,
    n: usize,
    y1: f64,
    y2: f64,
) -> (StillBackground, ColourFrame, [(f64, f64); 2]) {
    let pair = |k: usize| {
        let t = k as f64 - n as f64;
        [(48.0 + 1.5 * t, y1), (48.0 - 1.5 * t, y2)]
    };
    let mut m = StillBackground::new(cfg).expect("valid settings");
    for k in 0..n {
        m.place(&discs(k, &pair(k), 7), 0.0, &[]);
    }
    (m, discs(n, &pair(n), 7), pair(n))
}

#[test]
fn two_movers_side_by_side_are_each_placed_on_their_own_object() {
    // Two discs of radius 8 pass each other, one right along y = 26 and one left along y = 50:
    // at frame n their centres are 24 px apart, with 8 px of background between them. An
    // estimated flow's regions lean into each other (their halos join between the discs):
    // each region's centroid lies 5 px off its disc, towards the other.
    let n = 34;
    let (mut m, f, [a, b]) = passing(PlaceConfig::default(), n, 26.0, 50.0);
    let area = (2.0 * std::f64::consts::PI * R * R) as usize;
    let out = m.place(
        &f,
        0.0,
        &[((a.0, a.1 + 5.0), area), ((b.0, b.1 - 5.0), area)],
    );
    for (p, want) in out.iter().zip([a, b]) {
        match p {
            Placement::Moved { to } => {
                let err = (to.0 - want.0).hypot(to.1 - want.1);
                assert!(err < 1.5, "placed at {to:?}, object at {want:?}: {out:?}");
            }
            other => panic!("not placed: {other:?}"),
        }
    }
}

#[test]
fn regions_near_each_other_form_one_crowd_through_their_neighbours() {
    // Equivalent radii 10 px (area 314): within 2.5 × 20 = 50 px of each other is a crowd.
    let r = |x: f64| ((x, 0.0), 314);
    let regions = [r(0.0), r(45.0), r(90.0), r(200.0), r(400.0)];
    // 0 and 90 are 90 px apart but both near 45; 200 and 400 are alone.
    assert_eq!(
        crowds(&regions, &[0, 1, 2, 3, 4], 2.5),
        vec![vec![0, 1, 2], vec![3], vec![4]]
    );
    // Without 45 between them, 0 and 90 are no crowd.
    assert_eq!(
        crowds(&regions, &[0, 2, 3], 2.5),
        vec![vec![0], vec![2], vec![3]]
    );
    assert!(crowds(&regions, &[], 2.5).is_empty());
}

#[test]
fn a_merged_region_is_split_where_the_frame_shows_both_objects_and_not_where_it_shows_one() {
    // Two discs of radius 8 meet: one moves right along y = 30, the other left along
    // y = 46, their centres 16 px apart (8 px of background between them) at frame n.
    let (n, area) = (34, (4.0 * std::f64::consts::PI * R * R) as usize);
    let (mut m, f, [a, b]) = passing(PlaceConfig::default(), n, 30.0, 46.0);
    // The flow's one blob between them; the two tracks' predictions 3 px off their objects.
    let merged = [((48.0, 38.0), area)];
    let seeds = vec![vec![
        ((a.0 - 3.0, a.1), 1.2 * R),
        ((b.0 + 2.0, b.1 - 2.0), 1.2 * R),
    ]];
    let out = m.place_or_split(&f, 0.0, &merged, &seeds, &[]);
    match &out[0] {
        Placement::Split { to } => {
            // Each centre on its own object, nearer it than its seed (3 and 2.8 px off):
            // within 2.5 px, the kernel (radius 9.6) leaning a little to the other disc.
            assert_eq!(to.len(), 2);
            for ((got, want), (seed, _)) in to.iter().zip([a, b]).zip(&seeds[0]) {
                let err = (got.0 - want.0).hypot(got.1 - want.1);
                let before = (seed.0 - want.0).hypot(seed.1 - want.1);
                assert!(
                    err < 2.5 && err < before,
                    "split at {to:?}, objects at {a:?} and {b:?}"
                );
            }
        }
        other => panic!("not split: {other:?}"),
    }
    assert!(
        out[0]
            .describe()
            .starts_with("split between the tracks it hides")
    );
    // One seed alone splits nothing: the region is placed as any other.
    let (mut m, f) = model_at(n, moving);
    let truth = moving(n);
    let one = [(truth, (1.5 * std::f64::consts::PI * R * R) as usize)];
    let out = m.place_or_split(&f, 0.0, &one, &[vec![(truth, R)]], &[]);
    assert!(matches!(out[0], Placement::Moved { .. }), "{out:?}");
    // Two seeds on one object (one hides the other): both find the same centre, and the
    // region is not split.
    let (mut m, f) = model_at(n, moving);
    let seeds = vec![vec![
        ((truth.0 - 3.0, truth.1), R),
        ((truth.0 + 3.0, truth.1), R),
    ]];
    let out = m.place_or_split(&f, 0.0, &one, &seeds, &[]);
    assert!(!matches!(out[0], Placement::Split { .. }), "{out:?}");
    // Nor is it with the split turned off.
    let cfg = PlaceConfig {
        split: 0.0,
        ..PlaceConfig::default()
    };
    let (mut m, f, _) = passing(cfg, n, 30.0, 46.0);
    let seeds = vec![vec![
        ((a.0 - 3.0, a.1), 1.2 * R),
        ((b.0 + 2.0, b.1 - 2.0), 1.2 * R),
    ]];
    let out = m.place_or_split(&f, 0.0, &merged, &seeds, &[]);
    assert!(!matches!(out[0], Placement::Split { .. }), "{out:?}");
}

#[test]
fn a_pending_region_stands_only_on_an_object_of_its_own() {
    // Two discs of radius 8 pass each other 24 px apart (8 px of background between them).
    let n = 34;
    let area = (2.0 * std::f64::consts::PI * R * R) as usize;
    let (mut m, f, [a, b]) = passing(PlaceConfig::default(), n, 26.0, 50.0);
    // A weak detection on the second disc, beside the first disc's region: a mover of its
    // own, placed.
    let regions = [((a.0, a.1 + 3.0), area), ((b.0, b.1 - 3.0), area)];
    let out = m.place_or_split(&f, 0.0, &regions, &[], &[false, true]);
    for (p, want) in out.iter().zip([a, b]) {
        match p {
            Placement::Moved { to } => {
                assert!((to.0 - want.0).hypot(to.1 - want.1) < 1.5, "{out:?}")
            }
            other => panic!("not placed: {other:?}"),
        }
    }
    // A weak detection of half the area on the first disc's own object (a piece of it): the
    // two end on one blob, so it is refused, and the first region is placed without it (it
    // would keep its flow centroid beside an accepted region of that size).
    let (mut m, f, [a, _]) = passing(PlaceConfig::default(), n, 26.0, 50.0);
    let regions = [((a.0 - 3.0, a.1), area), ((a.0 + 5.0, a.1), area / 2)];
    let out = m.place_or_split(&f, 0.0, &regions, &[], &[false, true]);
    match &out[0] {
        Placement::Moved { to } => assert!((to.0 - a.0).hypot(to.1 - a.1) < 1.5, "{out:?}"),
        other => panic!("the object's own region not placed: {other:?}"),
    }
    assert!(
        matches!(&out[1], Placement::Kept(w) if w.contains("not placed on an object of its own")),
        "{out:?}"
    );
    // As an accepted region, the piece keeps both at their flow centroids.
    let (mut m, f, _) = passing(PlaceConfig::default(), n, 26.0, 50.0);
    let out = m.place_or_split(&f, 0.0, &regions, &[], &[]);
    assert!(
        out.iter().all(|p| matches!(p, Placement::Kept(_))),
        "{out:?}"
    );
    // Where nothing is placed (the camera moves), a pending region is refused too.
    let (mut m, f, [_, b]) = passing(PlaceConfig::default(), n, 26.0, 50.0);
    let out = m.place_or_split(&f, 3.0, &[(b, area)], &[], &[true]);
    assert!(matches!(&out[0], Placement::Kept(_)), "{out:?}");
    // A refused pending region masks nothing in the frame's background; a placed one does.
    let placed = [
        Placement::Moved { to: a },
        Placement::Kept("refused".into()),
    ];
    let got = covered(&regions, &[], &placed, 1.5, |i| i == 1);
    assert_eq!(got.len(), 1);
    assert_eq!(got[0].0, a);
    assert_eq!(covered(&regions, &[], &placed, 1.5, |_| false).len(), 2);
}
