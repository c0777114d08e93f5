//! `pins calibrate noise` end to end: flat fields captured through pins's own camera at a
//! known noise are written as 8-bit PNGs, the command recovers the noise into a camera config
//! that `pins simulate` takes, and bad capture sets are refused without output.

use std::path::Path;

use pins::imaging::pipeline::Camera;
use pins::imaging::{CameraConfig, NoiseConfig, psf_source};
use pins::io::{BitDepth, write_image};
use pins::types::Image;

mod common;
use common::{failed, ok, pins};

/// `levels` flat fields, `k` captures each, through the default camera with noise (a, b).
fn write_flats(dir: &Path, a: f32, b: f32, levels: &[f32], k: usize) {
    std::fs::create_dir_all(dir).unwrap();
    let cfg = CameraConfig {
        noise: NoiseConfig {
            a,
            b,
            ..NoiseConfig::default()
        },
        ..CameraConfig::default()
    };
    let (psf, _) = psf_source::load("delta").unwrap();
    let cam = Camera::new(&cfg, psf).unwrap();
    for (i, &l) in levels.iter().enumerate() {
        let scene = Image::filled(3, 80, 80, l);
        for j in 0..k {
            let im = cam.apply(&scene, (1000 * i + j) as u64).unwrap();
            write_image(
                &dir.join(format!("exp{i:02}_{j}.png")),
                &im,
                BitDepth::Eight,
            )
            .unwrap();
        }
    }
}

#[test]
fn noise_is_recovered_into_a_camera_config_that_simulate_takes() {
    let tmp = tempfile::tempdir().unwrap();
    let caps = tmp.path().join("caps");
    let levels: Vec<f32> = (0..10).map(|i| 0.05 + 0.1 * i as f32).collect();
    write_flats(&caps, 0.5, 20.0, &levels, 3);
    let out = tmp.path().join("fit");
    let text = ok(&pins(&[
        "calibrate",
        "noise",
        caps.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]));
    assert!(text.contains("a = "), "{text}");
    let cam: CameraConfig =
        serde_json::from_slice(&std::fs::read(out.join("camera.json")).unwrap()).unwrap();
    assert!((cam.noise.a / 0.5 - 1.0).abs() < 0.05, "{:?}", cam.noise);
    assert!((cam.noise.b / 20.0 - 1.0).abs() < 0.05, "{:?}", cam.noise);
    assert_eq!(cam.gamma, 1.7);
    for f in ["report.md", "report.json", "fit.png"] {
        assert!(out.join(f).is_file(), "{f}");
    }
    // The config is one `pins simulate` takes as it is.
    let scene = tmp.path().join("scene.png");
    write_image(&scene, &Image::filled(3, 16, 16, 0.5), BitDepth::Eight).unwrap();
    ok(&pins(&[
        "simulate",
        "--in",
        scene.to_str().unwrap(),
        "--out",
        tmp.path().join("sim.png").to_str().unwrap(),
        "--config",
        out.join("camera.json").to_str().unwrap(),
    ]));
}

#[test]
fn bad_capture_sets_are_refused_without_output() {
    let tmp = tempfile::tempdir().unwrap();
    let run = |caps: &Path| {
        let out = tmp.path().join("never");
        let err = failed(&pins(&[
            "calibrate",
            "noise",
            caps.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]));
        assert!(!out.exists(), "output written for {}", caps.display());
        err
    };
    // One capture per level: no temporal variance.
    let single = tmp.path().join("single");
    write_flats(&single, 0.2, 10.0, &[0.2, 0.5, 0.8], 1);
    assert!(run(&single).contains("at least two"));
    // Two levels only.
    let two = tmp.path().join("two");
    write_flats(&two, 0.2, 10.0, &[0.2, 0.5], 2);
    assert!(run(&two).contains("at least 3 levels"));
    // Saturated flats: every level clipped.
    let sat = tmp.path().join("saturated");
    write_flats(&sat, 0.2, 10.0, &[1.3, 1.4, 1.5], 2);
    assert!(run(&sat).contains("at least 3 levels"));
    // A JPEG, with the reason.
    let jpeg = tmp.path().join("jpeg");
    write_flats(&jpeg, 0.2, 10.0, &[0.2, 0.5, 0.8], 2);
    let im = Image::filled(3, 80, 80, 0.4);
    write_image(&jpeg.join("exp09_0.jpg"), &im, BitDepth::Eight).unwrap();
    write_image(&jpeg.join("exp09_1.jpg"), &im, BitDepth::Eight).unwrap();
    let e = run(&jpeg);
    assert!(e.contains("JPEG") && e.contains("compression"), "{e}");
    // Captures of two sizes.
    let mixed = tmp.path().join("mixed");
    write_flats(&mixed, 0.2, 10.0, &[0.2, 0.5, 0.8], 2);
    write_image(
        &mixed.join("exp09_0.png"),
        &Image::filled(3, 40, 40, 0.4),
        BitDepth::Eight,
    )
    .unwrap();
    write_image(
        &mixed.join("exp09_1.png"),
        &Image::filled(3, 40, 40, 0.4),
        BitDepth::Eight,
    )
    .unwrap();
    assert!(run(&mixed).contains("one camera setting"));
    // A name without a level.
    let unnamed = tmp.path().join("unnamed");
    std::fs::create_dir_all(&unnamed).unwrap();
    write_image(&unnamed.join("flat.png"), &im, BitDepth::Eight).unwrap();
    assert!(run(&unnamed).contains("LEVEL_N"));
}
