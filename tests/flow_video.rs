//! MMS on a video (`flow::video`) with the shipped weights: reusing each frame's features gives
//! the same flow to the last bit, a frame of another size starts the reuse over, the warm start
//! carries a steady motion, and `--iters auto` stops early but never runs more than asked.

use pins::flow::infer::Predictor;
use pins::flow::scale::predict_scaled;
use pins::flow::sequence::pair_flows_scaled;
use pins::flow::video::{VideoFlow, VideoOptions};
use pins::{Flow, Image};

/// A smooth, non-periodic texture moved by `shift` pixels (evaluated at the shifted position,
/// so every frame is exact).
fn scene(h: usize, w: usize, shift: (f32, f32)) -> Image {
    const WAVES: [(f32, f32, f32); 6] = [
        (0.113, 0.071, 0.3),
        (-0.052, 0.137, 1.1),
        (0.191, -0.043, 2.0),
        (0.029, 0.211, 0.7),
        (0.257, 0.163, 1.9),
        (-0.171, 0.093, 0.4),
    ];
    let mut img = Image::zeros(3, h, w);
    for c in 0..3 {
        for y in 0..h {
            for x in 0..w {
                let (xf, yf) = (x as f32 - shift.0, y as f32 - shift.1);
                let v: f32 = WAVES
                    .iter()
                    .enumerate()
                    .map(|(i, (fx, fy, p))| {
                        let k = 1.0 + 0.15 * ((i + c) % 3) as f32;
                        (k * (fx * xf + fy * yf) + p).sin() / 6.0
                    })
                    .sum();
                img.set(c, y, x, (0.5 + 0.45 * v).clamp(0.0, 1.0));
            }
        }
    }
    img
}

fn steady(n: usize, h: usize, w: usize, step: (f32, f32)) -> Vec<Image> {
    (0..n)
        .map(|i| scene(h, w, (step.0 * i as f32, step.1 * i as f32)))
        .collect()
}

fn epe(flow: &Flow, step: (f32, f32)) -> f64 {
    let (h, w) = (flow.height(), flow.width());
    let mut sum = 0.0;
    for y in 0..h {
        for x in 0..w {
            let (u, v) = flow.get(y, x);
            sum += (((u - step.0).powi(2) + (v - step.1).powi(2)) as f64).sqrt();
        }
    }
    sum / (h * w) as f64
}

#[test]
fn reuse_gives_the_same_flow_to_the_last_bit() {
    // The flow commands' predictor: coarse start and the variational refinement.
    let predictor = Predictor::load("mms-small").expect("built-in weights");
    let frames = steady(4, 96, 128, (2.5, -1.5));
    for scale in [1.0, 0.75] {
        let reused: Vec<_> = pair_flows_scaled(
            &predictor,
            frames.as_slice(),
            3,
            scale,
            VideoOptions::default(),
        )
        .expect("options")
        .collect::<pins::Result<_>>()
        .expect("flows");
        assert_eq!(reused.len(), 3);
        for (n, pair) in reused.iter().enumerate() {
            let alone =
                predict_scaled(&predictor, &frames[n], &frames[n + 1], 3, scale).expect("one pair");
            assert!(
                pair.flow == alone,
                "scale {scale}, pair {n}: reuse changed the flow"
            );
        }
    }
    // Which pairs reused: every one after the first.
    let mut video = VideoFlow::new(VideoOptions::default(), 1.0).expect("options");
    let used: Vec<bool> = (0..3)
        .map(|n| {
            video
                .pair(&predictor, &frames[n], &frames[n + 1], 2, 1.0)
                .expect("pair")
                .reused
        })
        .collect();
    assert_eq!(used, [false, true, true]);
}

#[test]
fn another_frame_starts_the_reuse_over() {
    let predictor = Predictor::load("mms-small")
        .expect("built-in weights")
        .with_coarse_start(false);
    let small = steady(3, 64, 80, (1.0, 1.0));
    let large = steady(2, 80, 96, (1.0, 1.0));
    let mut video = VideoFlow::new(VideoOptions::default(), 1.0).expect("options");
    // Consecutive, then a jump to other frames of another size, then a frame that is not the
    // previous pair's second (a skipped frame).
    let pairs: [(&Image, &Image, bool); 4] = [
        (&small[0], &small[1], false),
        (&small[1], &small[2], true),
        (&large[0], &large[1], false),
        (&small[0], &small[2], false),
    ];
    for (n, (a, b, reused)) in pairs.into_iter().enumerate() {
        let got = video.pair(&predictor, a, b, 2, 1.0).expect("pair");
        assert_eq!(got.reused, reused, "pair {n}");
        let alone = predictor.predict(a, b, 2).expect("alone");
        assert!(got.flow == alone, "pair {n}: the flow changed");
    }
}

#[test]
fn the_warm_start_carries_a_steady_motion() {
    let predictor = Predictor::load("mms-small")
        .expect("built-in weights")
        .with_coarse_start(false)
        .with_refine(&pins::flow::refine::Refine::None);
    let (h, w) = (160, 224);
    let step = (24.0, 10.0);
    let frames = steady(4, h, w, step);
    let warm = VideoOptions {
        warm_start: true,
        ..VideoOptions::default()
    };
    let run = |opts: VideoOptions| {
        let mut video = VideoFlow::new(opts, 1.0).expect("options");
        let pairs: Vec<_> = (0..3)
            .map(|n| {
                video
                    .pair(&predictor, &frames[n], &frames[n + 1], 2, 1.0)
                    .expect("pair")
            })
            .collect();
        (video, pairs)
    };
    let (_, cold) = run(VideoOptions::default());
    let (_, carried) = run(warm);
    for n in 0..3 {
        assert_eq!(carried[n].warm, n > 0, "pair {n}");
        let (ew, ec) = (epe(&carried[n].flow, step), epe(&cold[n].flow, step));
        if n == 0 {
            assert_eq!(ew, ec, "the first pair has nothing to carry");
        } else {
            // Two updates from the carried flow land far nearer a long motion than from zero.
            assert!(ew < 0.5 * ec, "pair {n}: warm {ew:.3} px, cold {ec:.3} px");
        }
    }
    // Half the gap, half the motion: the carried flow is scaled by the gaps' ratio, which
    // starts nearer than the unscaled one.
    let near = scene(h, w, (step.0 * 3.5, step.1 * 3.5));
    let half = (step.0 / 2.0, step.1 / 2.0);
    let from = |ratio: f64| {
        let (mut video, _) = run(warm);
        let pair = video
            .pair(&predictor, &frames[3], &near, 1, ratio)
            .expect("half gap");
        epe(&pair.flow, half)
    };
    let (scaled, unscaled) = (from(0.5), from(1.0));
    assert!(
        scaled < unscaled,
        "half the gap: scaled {scaled:.3} px, unscaled {unscaled:.3} px"
    );
    assert!(
        VideoFlow::new(warm, 1.0)
            .expect("options")
            .pair(&predictor, &frames[0], &frames[1], 1, 0.0)
            .is_err()
    );
}

#[test]
fn auto_iterations_stop_early_and_never_run_more_than_asked() {
    let predictor = Predictor::load("mms-small")
        .expect("built-in weights")
        .with_coarse_start(false)
        .with_refine(&pins::flow::refine::Refine::None);
    let frames = steady(2, 64, 96, (1.5, 0.5));
    let with = |px: f32| {
        let opts = VideoOptions {
            stop_px: Some(px),
            ..VideoOptions::default()
        };
        VideoFlow::new(opts, 1.0)
            .expect("options")
            .pair(&predictor, &frames[0], &frames[1], 12, 1.0)
            .expect("pair")
    };
    // Any update is below a huge threshold: one update.
    assert_eq!(with(1e6).iters, 1);
    // None is below a vanishing one: all twelve, and the flow of twelve fixed updates.
    let all = with(1e-9);
    assert_eq!(all.iters, 12);
    let fixed = predictor
        .predict(&frames[0], &frames[1], 12)
        .expect("fixed");
    let diff = all
        .flow
        .data()
        .iter()
        .zip(fixed.data())
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    assert!(diff < 1e-3, "auto at 12 updates differs by {diff} px");
    // The shipped threshold on a small steady motion settles before twelve.
    let auto = with(pins::flow::video::AUTO_STOP_PX);
    assert!(auto.iters < 12, "ran {} updates", auto.iters);
    for bad in [0.0, -1.0, f32::NAN] {
        let opts = VideoOptions {
            stop_px: Some(bad),
            ..VideoOptions::default()
        };
        assert!(VideoFlow::new(opts, 1.0).is_err(), "threshold {bad}");
    }
}

#[test]
fn infer_runs_frames_as_a_video_from_the_command_line() {
    let d = tempfile::tempdir().expect("temp dir");
    let frames = d.path().join("frames");
    std::fs::create_dir(&frames).expect("frames dir");
    for (n, f) in steady(3, 48, 64, (1.0, 0.5)).iter().enumerate() {
        pins::io::write_image(
            &frames.join(format!("{n:03}.png")),
            f,
            pins::io::BitDepth::Eight,
        )
        .expect("frame");
    }
    let run = |extra: &[&str], out: &str| {
        std::process::Command::new(env!("CARGO_BIN_EXE_pins"))
            .args(["infer", "--weights", "mms-small", "--refine", "none"])
            .arg("--frames")
            .arg(&frames)
            .arg("--out")
            .arg(d.path().join(out))
            .args(extra)
            .output()
            .expect("pins runs")
    };
    let ok = run(&["--iters", "auto", "--warm-start"], "flows");
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    let stdout = String::from_utf8_lossy(&ok.stdout);
    assert_eq!(
        stdout.lines().filter(|l| l.contains("iterations")).count(),
        2,
        "{stdout}"
    );
    assert!(d.path().join("flows/001.flo").exists());
    let bad = run(&["--iters", "often"], "bad");
    assert!(!bad.status.success());
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(err.contains("--iters") && err.contains("auto"), "{err}");
    assert!(!d.path().join("bad").exists(), "a refused run left output");
}
