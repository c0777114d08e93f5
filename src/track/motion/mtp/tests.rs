//! The trajectory predictor's tests (Note S13, Eqs. S20–S23): forecasts from the filtered
//! motion, a young track's first forecasts, `select`'s gate, the aligned motion, gaps.

use super::*;

fn region(x: f64, y: f64, speed: f64, dir: Option<f64>) -> Region {
    Region {
        colour: None,
        weak: false,
        pixels: 50,
        centroid: (x, y),
        speed,
        direction: dir,
        bbox: [0, 0, 1, 1],
        mean_flow: (0.0, 0.0),
        placed: None,
        foreground: None,
        aligned: None,
    }
}

/// An object moving 5 px a frame whose flow gives it 2 (MMS on a small mover) while the
/// frames confirm 5 (`Region::aligned`), its centre measured with ±1 px of noise: the
/// tracking filter, fed the flow's velocity, holds its centre behind the object; the
/// forecasts from the aligned filter's centre are closer one frame ahead. The reported
/// centre and the association's look-ahead stay the tracking filter's, and without
/// aligned motions the two filters are one.
#[test]
fn forecasts_start_from_the_filter_fed_with_the_frames_motion() {
    use rand_distr::{Distribution, StandardNormal};
    let run = |aligned_motion_r: Option<f64>, with_aligned: bool| {
        let mut rng = crate::rng::stream(21, &[0]);
        let mut normal = || -> f64 { Distribution::<f64>::sample(&StandardNormal, &mut rng) };
        let mut mtp = Mtp::new(MtpConfig {
            method: Some(Method::Poly),
            aligned_motion_r,
            ..MtpConfig::default()
        })
        .unwrap();
        let (mut sq, mut n, mut last) = (0.0, 0, None);
        for k in 0..40 {
            let x = 100.0 + 5.0 * k as f64;
            let mut r = region(x + normal(), 200.0 + normal(), 2.0, Some(0.0));
            if with_aligned {
                r.aligned = Some((5.0 + 0.3 * normal(), 0.3 * normal()));
            }
            let e = mtp.step(k, Some(&r), 1).unwrap();
            if k >= 10 {
                let (px, py) = e.path[0];
                sq += (px - (x + 5.0)).powi(2) + (py - 200.0).powi(2);
                n += 1;
            }
            last = Some(e);
        }
        ((sq / n as f64).sqrt(), last.unwrap())
    };
    let (tracking, t) = run(None, true);
    let (ahead, a) = run(Some(ALIGNED_MOTION_R), true);
    assert!(
        ahead < 0.6 * tracking && ahead < 2.0,
        "one frame ahead: {ahead:.2} px from the aligned filter, {tracking:.2} from the \
         tracking filter"
    );
    assert_eq!((a.centroid, a.next), (t.centroid, t.next));
    assert_ne!(a.path, t.path);
    // No aligned motion: the same forecasts either way.
    assert_eq!(run(None, false).1, run(Some(ALIGNED_MOTION_R), false).1);
    // A variance that is not one is refused.
    for bad in [0.0, -1.0, f64::NAN] {
        let c = MtpConfig {
            aligned_motion_r: Some(bad),
            ..MtpConfig::default()
        };
        assert!(Mtp::new(c).is_err(), "{bad}");
    }
}

/// A new track on an object moving 3 px a frame along a straight line, its speed and
/// direction samples noisy (±0.4 px/frame, ±6°): over its first ten frames the paper's
/// quadratic through the few samples there are runs its 30-frame forecast far off; waiting
/// for five samples per order keeps it near the line.
#[test]
fn a_new_track_s_first_forecasts_wait_for_their_samples() {
    use rand_distr::{Distribution, StandardNormal};
    let worst = |per_order: usize| {
        let mut rng = crate::rng::stream(11, &[per_order as u64]);
        let mut normal = || -> f64 { Distribution::<f64>::sample(&StandardNormal, &mut rng) };
        let mut mtp = Mtp::new(MtpConfig {
            samples_per_order: Some(per_order),
            ..MtpConfig::default()
        })
        .unwrap();
        let mut worst = 0.0f64;
        for n in 0..10 {
            let x = 100.0 + 3.0 * n as f64;
            let r = region(x, 200.0, 3.0 + 0.4 * normal(), Some(0.1 * normal()));
            let e = mtp.step(n, Some(&r), 30).unwrap();
            let truth = x + 90.0;
            worst = worst.max((e.path[29].0 - truth).hypot(e.path[29].1 - 200.0));
        }
        worst
    };
    let (interpolating, waiting) = (worst(1), worst(SAMPLES_PER_ORDER_MEASURED));
    assert!(
        waiting < 45.0 && waiting < 0.2 * interpolating,
        "worst 30-frame error over the first ten frames: {waiting:.1} px waiting, \
         {interpolating:.1} px interpolating"
    );
    for bad in [-1.0, f64::NAN, f64::INFINITY] {
        let c = MtpConfig {
            trend_reach: Some(bad),
            ..MtpConfig::default()
        };
        assert!(c.validate().is_err(), "{bad}");
    }
    let zero = MtpConfig {
        samples_per_order: Some(0),
        ..MtpConfig::default()
    };
    assert!(zero.validate().is_err());
}

/// A young track speeding up along a line: with the trend's reach 1, the forecast follows
/// the fitted trend for as many frames as the window spans and then moves at a constant
/// velocity; with 0 it follows the fit over all 30 frames.
#[test]
fn a_young_track_s_trend_is_followed_as_far_as_its_window_spans() {
    let steps = |reach: f64| {
        let mut mtp = Mtp::new(MtpConfig {
            samples_per_order: Some(1),
            trend_reach: Some(reach),
            ..MtpConfig::default()
        })
        .unwrap();
        let mut e = None;
        for n in 0..8 {
            let r = region(3.0 * n as f64, 50.0, 2.0 + 0.2 * n as f64, Some(0.0));
            e = Some(mtp.step(n, Some(&r), 30).unwrap());
        }
        let path = e.unwrap().path;
        // Per-frame steps along x: [29].
        path.windows(2)
            .map(|w| w[1].0 - w[0].0)
            .collect::<Vec<f64>>()
    };
    // Eight samples span 7 frames: held from 7 frames ahead, so every step from there on
    // (steps[k] is the move from k + 1 to k + 2 frames ahead) is the same.
    let held = steps(1.0);
    assert!(
        held[6..].iter().all(|s| (s - held[6]).abs() < 1e-9),
        "{held:?}"
    );
    let followed = steps(0.0);
    // Up to the hold the two agree; 30 frames ahead the followed ramp runs on.
    assert!(
        held[..6]
            .iter()
            .zip(&followed)
            .all(|(h, f)| (h - f).abs() < 1e-9)
    );
    assert!(
        (followed[28] - held[28]).abs() > 0.5,
        "{followed:?} {held:?}"
    );
}

/// On a path whose direction swings (where `select` comes to prefer the constant velocity
/// one frame ahead), a `select` track is still looked for where the fit puts it next frame,
/// while its forecasts are its choice.
#[test]
fn select_gates_on_the_fit_and_forecasts_its_choice() {
    let run = |method: Method| {
        let mut mtp = Mtp::new(MtpConfig {
            method: Some(method),
            ..MtpConfig::default()
        })
        .unwrap();
        let mut out = Vec::new();
        for n in 0..60 {
            let t = n as f64;
            let dir = 0.8 * (t / 3.0).sin();
            let (x, y) = (4.0 * t, 100.0 + 30.0 * (t / 3.0).sin());
            let r = region(x, y, 4.0, Some(dir));
            out.push(mtp.step(n, Some(&r), 15).unwrap());
        }
        out
    };
    let (select, poly) = (run(Method::Select), run(Method::Poly));
    let mut chose_other = 0;
    for (s, p) in select.iter().zip(&poly) {
        assert_eq!(s.next, p.path[0], "frame {}", s.frame);
        assert_eq!(p.next, p.path[0]);
        chose_other += usize::from(s.path != p.path);
    }
    // The choice did differ from the fit somewhere, so the test means something.
    assert!(chose_other > 0);
}

/// Placed centroids move 5 px a frame while the flow says 3 (a small mover's flow falls
/// short): the filter's velocity follows the centroids' displacement (most of the way: the
/// flow still enters the filter), the flow's does not.
#[test]
fn the_filter_velocity_corrects_a_flow_that_falls_short() {
    let run = |source: MotionSource| {
        let mut mtp = Mtp::new(MtpConfig {
            motion_source: source,
            position_r: 1.0,
            placed_motion_r: 4.0,
            ..MtpConfig::default()
        })
        .unwrap();
        let mut last = None;
        for n in 0..40 {
            let mut r = region(0.0, 50.0, 3.0, Some(0.0));
            r.placed = Some((10.0 + 5.0 * n as f64, 50.0));
            last = Some(mtp.step(n, Some(&r), 15).unwrap());
        }
        let e = last.unwrap();
        (e.path[14].0 - (10.0 + 5.0 * 54.0)).abs()
    };
    let (flow, filter) = (run(MotionSource::Flow), run(MotionSource::Auto));
    assert!(
        filter < 10.0 && filter < 0.5 * flow,
        "15 frames ahead: filter off by {filter:.1} px, flow by {flow:.1}"
    );
}

/// The flow says 2 px/frame where the object moves 6 (a small mover's estimate) and the
/// alignment found the 6: the fits' samples take the aligned motion, so the forecast
/// 15 frames ahead follows the object; without it, the flow's shortfall is extrapolated.
#[test]
fn the_aligned_motion_feeds_the_fits() {
    let run = |aligned: bool| {
        let mut mtp = Mtp::new(MtpConfig::default()).unwrap();
        let mut last = None;
        for n in 0..40 {
            let mut r = region(10.0 + 6.0 * n as f64, 50.0, 2.0, Some(0.0));
            r.placed = Some(r.centroid);
            r.aligned = aligned.then_some((6.0, 0.0));
            last = Some(mtp.step(n, Some(&r), 15).unwrap());
        }
        let e = last.unwrap();
        (e.path[14].0 - (10.0 + 6.0 * 54.0)).abs()
    };
    let (with, without) = (run(true), run(false));
    assert!(
        with < 3.0 && with < 0.3 * without,
        "15 frames ahead: aligned off by {with:.1} px, flow by {without:.1}"
    );
}

#[test]
fn predicts_a_straight_path_and_survives_gaps_and_still_objects() {
    let mut mtp = Mtp::new(MtpConfig::default()).unwrap();
    let mut last = None;
    for n in 0..60 {
        let seen = if n % 7 == 3 {
            None
        } else {
            Some(region(10.0 + 2.0 * n as f64, 50.0, 2.0, Some(0.0)))
        };
        last = Some(mtp.step(n, seen.as_ref(), 15).unwrap());
    }
    let e = last.unwrap();
    let (px, py) = e.path[14];
    assert!(
        (px - (e.centroid.0 + 30.0)).abs() < 1.0 && (py - 50.0).abs() < 0.5,
        "{:?}",
        e.path[14]
    );
    let mut still = Mtp::new(MtpConfig::default()).unwrap();
    for n in 0..10 {
        let e = still
            .step(n, Some(&region(5.0, 5.0, 0.0, None)), 30)
            .unwrap();
        assert!(e.path.iter().all(|p| (p.0 - 5.0).abs() < 1e-6));
    }
    let mut cv = Mtp::new(MtpConfig {
        method: Some(Method::ConstantVelocity),
        ..MtpConfig::default()
    })
    .unwrap();
    let mut e = None;
    for n in 0..40 {
        let r = region(10.0 + 2.0 * n as f64, 50.0 - n as f64, 5f64.sqrt(), None);
        e = Some(cv.step(n, Some(&r), 10).unwrap());
    }
    let e = e.unwrap();
    let (dx, dy) = (e.path[9].0 - e.centroid.0, e.path[9].1 - e.centroid.1);
    assert!(
        (dx - 20.0).abs() < 0.5 && (dy + 10.0).abs() < 0.5,
        "{dx} {dy}"
    );
    assert!(
        Mtp::new(MtpConfig {
            window: 0,
            ..MtpConfig::default()
        })
        .is_err()
    );
}
