//! The live tracker on a stream it cannot keep up with (`track::motion::step`,
//! `live::clock`): processed frames 1 to 4 stream frames apart, in an uneven order, each pair's
//! exact flow over its gap. Told each pair's time and span, the tracker predicts where the
//! object is at the next processed frame and reports its motion per stream frame; fed the same
//! pairs as if they were consecutive frames, it mispredicts by the gaps' changes.

use pins::live::tracking::LiveTracker;
use pins::scene::trajectory::{ObjectSpec, PathKind, TrajectoryConfig};
use pins::track::config::{Profile, TrackConfig};
use pins::track::motion::step::{Step, along};

/// The processed frames: gaps of 1–4 stream frames, in no steady order.
const KEPT: [usize; 24] = [
    0, 1, 4, 6, 10, 11, 14, 16, 20, 23, 24, 27, 30, 32, 36, 37, 40, 43, 45, 48, 52, 53, 56, 59,
];

fn scene() -> TrajectoryConfig {
    TrajectoryConfig {
        width: 160,
        height: 120,
        fps: 15.0,
        frames: 60,
        seed: 5,
        objects: vec![ObjectSpec {
            path: PathKind::Sinusoid,
            radius: 8.0,
            ..ObjectSpec::default()
        }],
    }
}

/// Per processed pair after the track is confirmed: the error (px) of the prediction of the
/// object's centre at the next processed frame, and of its velocity (px per stream frame)
/// against the pair's mean motion.
fn run(kept: &[usize], aware: bool) -> (Vec<f64>, Vec<f64>) {
    let sc = scene();
    let mut opts = TrackConfig::default()
        .options(Profile::Exact, false)
        .expect("default options");
    opts.horizons = vec![1, 4];
    let mut tracker = LiveTracker::new(opts).expect("tracker");
    let (mut position, mut velocity) = (Vec::new(), Vec::new());
    for (k, w) in kept.windows(2).enumerate() {
        let (a, b) = (w[0], w[1]);
        let flow = sc.flow_between(a, b).expect("flow");
        let step = if aware {
            Step::new(a as f64, (b - a) as f64).expect("step")
        } else {
            Step::every(k)
        };
        let objects = tracker.step(step, &flow, None).expect("tracking");
        let Some(o) = objects.first() else { continue };
        // The next processed frame: `b`, the flow's span ahead (one step for the blind one).
        let ahead = if aware { (b - a) as f64 } else { 1.0 };
        let path: Vec<(f64, f64)> = o.path.iter().map(|p| (p[0], p[1])).collect();
        let p = along((o.centroid[0], o.centroid[1]), &path, ahead);
        // The object at b moved on to wherever its flow from b says; the track's centre at
        // `a` is the region's, so the prediction is compared with b's region centre: a's plus
        // the motion over the gap.
        let (ta, tb) = (sc.centroid(0, a), sc.centroid(0, b));
        let (cx, cy) = (o.centroid[0] + tb.0 - ta.0, o.centroid[1] + tb.1 - ta.1);
        position.push((p.0 - cx).hypot(p.1 - cy));
        let per_frame = (
            (tb.0 - ta.0) / (b - a) as f64,
            (tb.1 - ta.1) / (b - a) as f64,
        );
        let scale = if aware { 1.0 } else { (b - a) as f64 };
        velocity
            .push((o.velocity[0] / scale - per_frame.0).hypot(o.velocity[1] / scale - per_frame.1));
    }
    (position, velocity)
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

#[test]
fn the_tracker_told_the_gaps_predicts_the_next_processed_frame() {
    let (aware_pos, aware_vel) = run(&KEPT, true);
    let (blind_pos, _) = run(&KEPT, false);
    // The same clip at a steady 1 frame in 3 (a longer mean gap than KEPT's 2.6).
    let steady: Vec<usize> = (0..60).step_by(3).collect();
    let (steady_pos, _) = run(&steady, true);
    // The object is followed from its confirmation to the end.
    assert!(
        aware_pos.len() >= KEPT.len() - 6,
        "followed on {} of {} pairs",
        aware_pos.len(),
        KEPT.len() - 1
    );
    let (a, b) = (mean(&aware_pos), mean(&blind_pos));
    eprintln!(
        "at the next processed frame: told the gaps {a:.2} px on {} pairs {aware_pos:.2?}; \
         blind {b:.2} px on {} pairs",
        aware_pos.len(),
        blind_pos.len()
    );
    assert!(a < 2.0, "told the gaps: {a:.2} px ({aware_pos:?})");
    // Uneven gaps cost nothing beyond their length: no worse than a steady, longer gap.
    let s = mean(&steady_pos);
    assert!(
        a <= s,
        "uneven gaps {a:.2} px against a steady 1 in 3 {s:.2} px"
    );
    // Blind, the gaps' changes break the velocity gate: the object is lost, or mispredicted.
    assert!(
        blind_pos.len() < aware_pos.len() / 2 || b > 2.0 * a,
        "blind: {b:.2} px on {} pairs",
        blind_pos.len()
    );
    // Its velocity is per stream frame: within 0.5 px/frame of the pair's mean motion.
    let v = mean(&aware_vel);
    assert!(v < 0.5, "velocity error {v:.2} px/frame ({aware_vel:?})");
}

#[test]
fn time_that_does_not_advance_is_refused() {
    let sc = scene();
    let opts = TrackConfig::default()
        .options(Profile::Exact, false)
        .expect("default options");
    let mut tracker = LiveTracker::new(opts).expect("tracker");
    let flow = sc.flow_between(0, 2).expect("flow");
    tracker
        .step(Step::new(3.0, 2.0).expect("step"), &flow, None)
        .expect("first step");
    let err = tracker
        .step(Step::new(3.0, 2.0).expect("step"), &flow, None)
        .expect_err("the same time twice");
    assert!(err.to_string().contains("time must increase"), "{err}");
}
