//! Tests of the coarse-to-fine refinement (`refine`) and its settings (`RefineConfig`).

use super::*;

/// A smooth, textured grey frame and the same frame moved by `(du, dv)`: frame 2 at `p` is
/// frame 1 at `p − (du, dv)`, so the true flow is `(du, dv)` everywhere.
fn moved_pair(h: usize, w: usize, du: f32, dv: f32) -> (Image, Image) {
    let f = |x: f32, y: f32| {
        0.5 + 0.2 * (0.31 * x + 0.1 * y).sin() * (0.23 * y).cos()
            + 0.1 * (0.11 * x * x.sqrt().max(1.0) / 4.0 - 0.17 * y).sin()
    };
    let a: Vec<f32> = (0..h * w)
        .map(|i| f((i % w) as f32, (i / w) as f32))
        .collect();
    let b: Vec<f32> = (0..h * w)
        .map(|i| f((i % w) as f32 - du, (i / w) as f32 - dv))
        .collect();
    (
        Image::from_vec(1, h, w, a).unwrap(),
        Image::from_vec(1, h, w, b).unwrap(),
    )
}

fn epe(flow: &Flow, du: f32, dv: f32, border: usize) -> f64 {
    let (h, w) = (flow.height(), flow.width());
    let mut s = 0.0;
    let mut n = 0;
    for y in border..h - border {
        for x in border..w - border {
            let (u, v) = flow.get(y, x);
            s += (((u - du).powi(2) + (v - dv).powi(2)) as f64).sqrt();
            n += 1;
        }
    }
    s / n as f64
}

/// A flow that is off by up to 1.5 px (a smooth error, as a 1/8-resolution estimate is)
/// is brought to within a tenth of a pixel of the true sub-pixel motion.
#[test]
fn recovers_sub_pixel_motion_from_a_rough_start() {
    let (h, w) = (96, 128);
    let (du, dv) = (2.3f32, -1.6f32);
    let (a, b) = moved_pair(h, w, du, dv);
    let mut start = Flow::zeros(h, w);
    for y in 0..h {
        for x in 0..w {
            let e = 1.5 * ((x as f32 / w as f32) - 0.5);
            start.set(y, x, du + e, dv - 0.8 * e + 0.3);
        }
    }
    let before = epe(&start, du, dv, 8);
    let out = refine(&a, &b, &start, &RefineConfig::default()).unwrap();
    let after = epe(&out, du, dv, 8);
    assert!(before > 0.5, "{before}");
    assert!(after < 0.1, "EPE {before:.3} → {after:.3}");
}

/// The default sweeps solve the energy: from the start the network leaves for a sub-pixel
/// motion (nothing reported, a smooth error up to a pixel), the default result is as near
/// the truth as sixteen times the iterations get, and near their flow. ω = 1.6 (OpenCV's,
/// which starts from DIS's patch search) stops far short of both here.
#[test]
fn default_sweeps_reach_the_minimum_from_a_network_start() {
    let (h, w) = (96, 128);
    let (du, dv) = (0.6f32, -0.45f32);
    let (a, b) = moved_pair(h, w, du, dv);
    let start = Flow::zeros(h, w);
    let converged = RefineConfig {
        fixed_point_iters: 20,
        sor_iters: 20,
        ..RefineConfig::default()
    };
    let run = |cfg: &RefineConfig| refine(&a, &b, &start, cfg).unwrap();
    let (best, default) = (run(&converged), run(&RefineConfig::default()));
    let opencv = run(&RefineConfig {
        omega: 1.6,
        ..RefineConfig::default()
    });
    let gap = |f: &Flow| {
        let d = f.data().iter().zip(best.data()).map(|(x, y)| (x - y).abs());
        d.sum::<f32>() / f.data().len() as f32
    };
    let (e_best, e_default, e_opencv) = (
        epe(&best, du, dv, 8),
        epe(&default, du, dv, 8),
        epe(&opencv, du, dv, 8),
    );
    eprintln!(
        "EPE converged {e_best:.4}, default {e_default:.4}, ω 1.6 {e_opencv:.4}; \
         mean gap to converged {:.4} and {:.4}",
        gap(&default),
        gap(&opencv)
    );
    assert!(
        e_default < 1.2 * e_best + 0.01,
        "{e_default} against {e_best}"
    );
    assert!(gap(&default) < 0.5 * gap(&opencv));
}

/// Two textured halves moving apart, their boundary on an intensity step: the local
/// smoothness weight (κ) keeps the two motions apart near the boundary, where one α
/// everywhere blurs them into each other.
#[test]
fn the_local_weight_keeps_a_motion_boundary_on_an_image_edge() {
    let (h, w) = (64, 96);
    let tex = |x: f32, y: f32| 0.1 * (0.7 * x + 0.3 * y).sin() * (0.45 * y - 0.2 * x).cos();
    let (d_left, d_right) = (1.5f32, -1.0f32);
    let frame = |shift_l: f32, shift_r: f32| {
        let data: Vec<f32> = (0..h * w)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                if (i % w) < w / 2 {
                    0.3 + tex(x - shift_l, y)
                } else {
                    0.7 + tex(x - shift_r + 17.0, y)
                }
            })
            .collect();
        Image::from_vec(1, h, w, data).unwrap()
    };
    let (a, b) = (frame(0.0, 0.0), frame(d_left, d_right));
    let near = |f: &Flow| {
        let (mut s, mut n) = (0.0f64, 0);
        for y in 8..h - 8 {
            for x in w / 2 - 4..w / 2 + 4 {
                let d = if x < w / 2 { d_left } else { d_right };
                let (u, v) = f.get(y, x);
                s += (((u - d).powi(2) + v * v) as f64).sqrt();
                n += 1;
            }
        }
        s / n as f64
    };
    let run = |kappa: f32| {
        let cfg = RefineConfig {
            kappa,
            ..RefineConfig::default()
        };
        near(&refine(&a, &b, &Flow::zeros(h, w), &cfg).unwrap())
    };
    let (flat, local) = (run(0.0), run(RefineConfig::default().kappa));
    eprintln!("EPE within 4 px of the boundary: κ 0 {flat:.3}, κ default {local:.3}");
    assert!(local < 0.95 * flat, "{local} against {flat}");
}

/// The result does not depend on the number of threads (red–black sweeps).
#[test]
fn same_result_on_one_and_two_threads() {
    let (a, b) = moved_pair(40, 56, 1.2, 0.7);
    let start = Flow::zeros(40, 56);
    let run = |n: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .unwrap()
            .install(|| refine(&a, &b, &start, &RefineConfig::default()).unwrap())
    };
    assert_eq!(run(1), run(2));
}

/// Frames without any texture hold no evidence: a constant flow stays as it was, and a
/// black or saturated frame gives finite flow.
#[test]
fn flat_frames_keep_the_flow_and_stay_finite() {
    for level in [0.0f32, 0.5, 1.0] {
        let img = Image::filled(3, 33, 47, level);
        let mut start = Flow::zeros(33, 47);
        for y in 0..33 {
            for x in 0..47 {
                start.set(y, x, 3.5, -1.25);
            }
        }
        let out = refine(&img, &img, &start, &RefineConfig::default()).unwrap();
        for (o, s) in out.data().iter().zip(start.data()) {
            assert!((o - s).abs() < 1e-4, "level {level}: {o} against {s}");
        }
    }
}

/// Tiny frames, including ones smaller than every scale's derivative stencil, never panic.
#[test]
fn tiny_frames_are_handled() {
    for (h, w) in [(1, 1), (1, 9), (2, 2), (3, 5), (7, 4), (9, 17)] {
        let (a, b) = moved_pair(h, w, 0.5, 0.0);
        let out = refine(&a, &b, &Flow::zeros(h, w), &RefineConfig::default()).unwrap();
        assert!(out.data().iter().all(|x| x.is_finite()));
    }
}

#[test]
fn bad_inputs_are_errors() {
    let (a, b) = moved_pair(16, 16, 0.5, 0.0);
    let (c, _) = moved_pair(16, 17, 0.5, 0.0);
    let cfg = RefineConfig::default();
    assert!(refine(&a, &c, &Flow::zeros(16, 16), &cfg).is_err());
    assert!(refine(&a, &b, &Flow::zeros(15, 16), &cfg).is_err());
    let mut nan = Flow::zeros(16, 16);
    nan.set(3, 3, f32::NAN, 0.0);
    let e = refine(&a, &b, &nan, &cfg).unwrap_err().to_string();
    assert!(e.contains("non-finite"), "{e}");
    for bad in [
        RefineConfig {
            scales: vec![],
            ..cfg.clone()
        },
        RefineConfig {
            scales: vec![0],
            ..cfg.clone()
        },
        RefineConfig {
            omega: 2.0,
            ..cfg.clone()
        },
        RefineConfig {
            alpha: f32::NAN,
            ..cfg.clone()
        },
    ] {
        assert!(bad.validate("refine").is_err(), "{bad:?}");
    }
    assert!(Refine::parse("variational").is_ok() && Refine::parse("tv-l1").is_err());
}

/// `--refine FILE.json`: the settings it names over the defaults; a bad field, a value out
/// of range or a missing file is an error naming it.
#[test]
fn settings_from_a_json_file() {
    let d = tempfile::tempdir().unwrap();
    let good = d.path().join("r.json");
    std::fs::write(&good, r#"{"scales": [2, 1], "alpha": 10}"#).unwrap();
    let cfg = Refine::parse(good.to_str().unwrap())
        .unwrap()
        .config()
        .unwrap();
    assert_eq!((cfg.scales.clone(), cfg.alpha), (vec![2, 1], 10.0));
    assert_eq!(cfg.delta, RefineConfig::default().delta);
    for (name, text, says) in [
        ("unknown.json", r#"{"scale": [1]}"#, "unknown field"),
        ("range.json", r#"{"omega": 3}"#, "omega"),
    ] {
        let p = d.path().join(name);
        std::fs::write(&p, text).unwrap();
        let e = Refine::parse(p.to_str().unwrap()).unwrap_err().to_string();
        assert!(e.contains(says), "{e}");
    }
    let e = Refine::parse(d.path().join("none.json").to_str().unwrap()).unwrap_err();
    assert!(e.to_string().contains("none.json"), "{e}");
}

/// A small mover the start resolves (Note S12's r = 3 disc, 15 px a frame, over a textured
/// still background) keeps its motion: at 1/4 resolution the disc is under 2 px, and a coarse
/// pass's increment, brought back to full size, would otherwise smooth its flow into the
/// background, which the finer passes' linearisation cannot bring back from 15 px away.
#[test]
fn a_small_fast_mover_survives_the_coarse_passes() {
    let (h, w) = (96, 128);
    let (bg, _) = moved_pair(h, w, 0.0, 0.0);
    let (r, (cx, cy), du) = (3.0f32, (40.0f32, 48.0f32), 15.0f32);
    let disc = |x: f32, y: f32, ox: f32| ((x - cx - ox).powi(2) + (y - cy).powi(2)).sqrt() <= r;
    let frame = |ox: f32| {
        let data = (0..h * w)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                if disc(x, y, ox) { 0.95 } else { bg.plane(0)[i] }
            })
            .collect();
        Image::from_vec(1, h, w, data).unwrap()
    };
    let (a, b) = (frame(0.0), frame(du));
    let mut start = Flow::zeros(h, w);
    let mut inside = vec![];
    for y in 0..h {
        for x in 0..w {
            if disc(x as f32, y as f32, 0.0) {
                start.set(y, x, du, 0.0);
                inside.push((y, x));
            }
        }
    }
    let out = refine(&a, &b, &start, &RefineConfig::default()).unwrap();
    let mean = inside.iter().map(|&(y, x)| out.get(y, x).0).sum::<f32>() / inside.len() as f32;
    // Without the fade the coarse passes leave about 3 px of the 15.
    assert!(mean > 8.0, "the disc's mean flow {mean:.2} px of {du}");
}

/// Near a motion boundary blurred by the metalens (the shipped PSF spreads 90 % of a point's
/// light over 16 px), the second frame is not a warp of the first by the true motion, and a
/// coarse pass would drag a correct flow towards the blur's apparent motion for tens of pixels
/// around the boundary. Started from the exact flow of a textured square moving 12 px over a
/// still textured background, both frames through that PSF, the refinement keeps the flow
/// near it: measured 0.42 px of EPE within 24 px of the square's edge (0.57 px when the fade's
/// weight was averaged over one coarse pixel and not first eroded over the derivatives' reach).
#[test]
fn a_blurred_motion_boundary_keeps_a_correct_flow() {
    let (h, w) = (160, 192);
    let (bg, _) = moved_pair(h, w, 0.0, 0.0);
    let tex = |x: f32, y: f32| 0.5 + 0.3 * (0.41 * x - 0.2 * y).sin() * (0.37 * y + 0.1 * x).cos();
    let (x0, y0, side, du) = (60.0f32, 50.0f32, 60.0f32, 12.0f32);
    let inside = |x: f32, y: f32, ox: f32| {
        (x0 + ox..x0 + ox + side).contains(&x) && (y0..y0 + side).contains(&y)
    };
    let (psf, _) = crate::imaging::psf_source::load("default").unwrap();
    let psf = psf.to_mono();
    let (kh, kw) = psf.size();
    let frame = |ox: f32| {
        let p: Vec<f32> = (0..h * w)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                if inside(x, y, ox) {
                    tex(x - ox, y)
                } else {
                    bg.plane(0)[i]
                }
            })
            .collect();
        let blurred = crate::imaging::convolve::convolve_plane(
            &p,
            h,
            w,
            psf.channel(0),
            kh,
            kw,
            crate::imaging::convolve::ConvMethod::Auto,
        );
        Image::from_vec(1, h, w, blurred).unwrap()
    };
    let (a, b) = (frame(0.0), frame(du));
    let mut truth = Flow::zeros(h, w);
    for y in 0..h {
        for x in 0..w {
            if inside(x as f32, y as f32, 0.0) {
                truth.set(y, x, du, 0.0);
            }
        }
    }
    let out = refine(&a, &b, &truth, &RefineConfig::default()).unwrap();
    // Pixels within 24 px of the square's edge (inside or out), away from the frame's border.
    let near = |x: f32, y: f32| {
        let (cx, cy) = (x0 + side / 2.0, y0 + side / 2.0);
        let d = ((x - cx).abs() - side / 2.0).max((y - cy).abs() - side / 2.0);
        d.abs() <= 24.0
    };
    let (mut s, mut n) = (0.0f64, 0);
    for y in 8..h - 8 {
        for x in 8..w - 8 {
            if near(x as f32, y as f32) {
                let ((u, v), (tu, tv)) = (out.get(y, x), truth.get(y, x));
                s += ((u - tu).hypot(v - tv)) as f64;
                n += 1;
            }
        }
    }
    let e = s / n as f64;
    assert!(e < 0.5, "EPE {e:.3} px near the blurred boundary");
}
