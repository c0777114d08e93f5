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

/// `k` captures of a point source at (x, y) through the default camera, its peak at `peak` of
/// full scale (above 1: the core saturates), written as `NAME_N.png`.
fn write_point(dir: &Path, name: &str, peak: f32, k: usize) -> pins::optics::Psf {
    std::fs::create_dir_all(dir).unwrap();
    let (psf, _) = psf_source::load("default").unwrap();
    let top = psf.image().data().iter().fold(0.0f32, |m, &v| m.max(v));
    let cam = Camera::new(&CameraConfig::default(), psf.clone()).unwrap();
    let mut scene = Image::zeros(3, 180, 200);
    for c in 0..3 {
        scene.set(c, 90, 100, peak / (0.8 * top));
    }
    for j in 0..k {
        let im = cam.apply(&scene, j as u64).unwrap();
        write_image(&dir.join(format!("{name}_{j}.png")), &im, BitDepth::Eight).unwrap();
    }
    psf
}

#[test]
fn a_psf_is_measured_from_a_point_source_at_two_exposures() {
    let tmp = tempfile::tempdir().unwrap();
    let caps = tmp.path().join("point");
    let truth = write_point(&caps, "short", 0.9, 12);
    write_point(&caps, "long", 27.0, 12);
    let out = tmp.path().join("psf.npy");
    let text = ok(&pins(&[
        "calibrate",
        "psf",
        caps.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]));
    assert!(text.contains("80 % of the energy"), "{text}");
    let (est, _) = psf_source::load(out.to_str().unwrap()).unwrap();
    let (re, rt) = (
        pins::imaging::calibrate::point_source::encircled_radius(&est, 0.8),
        pins::imaging::calibrate::point_source::encircled_radius(&truth, 0.8),
    );
    assert!((re / rt - 1.0).abs() < 0.05, "EE80 {re} px against {rt}");
    // `pins simulate` takes the file as its PSF.
    let scene = tmp.path().join("scene.png");
    write_image(&scene, &Image::filled(3, 16, 16, 0.5), BitDepth::Eight).unwrap();
    ok(&pins(&[
        "simulate",
        "--in",
        scene.to_str().unwrap(),
        "--out",
        tmp.path().join("sim.png").to_str().unwrap(),
        "--psf",
        out.to_str().unwrap(),
    ]));
    // No point source: refused, nothing written.
    let dark = tmp.path().join("nothing");
    write_flats(&dark, 0.2, 10.0, &[0.0], 2);
    let never = tmp.path().join("never.npy");
    let e = failed(&pins(&[
        "calibrate",
        "psf",
        dark.to_str().unwrap(),
        "--out",
        never.to_str().unwrap(),
    ]));
    assert!(e.contains("noise floor") && !never.exists(), "{e}");
}

#[test]
fn the_measured_diffusercam_psf_is_centred_and_normalised() {
    let Some(data) = common::shared_data() else {
        eprintln!("SKIPPED: ../shared/data not found (the DiffuserCam PSF)");
        return;
    };
    let tif = data.join("psf_diffusercam/psf_sample.tif");
    if !tif.is_file() {
        eprintln!("SKIPPED: {} not found", tif.display());
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let caps = tmp.path().join("diffuser");
    std::fs::create_dir_all(&caps).unwrap();
    std::fs::copy(&tif, caps.join("psf_0.tif")).unwrap();
    let out = tmp.path().join("psf.npy");
    let text = ok(&pins(&[
        "calibrate",
        "psf",
        caps.to_str().unwrap(),
        "--gamma",
        "1",
        "--out",
        out.to_str().unwrap(),
    ]));
    eprintln!("{text}");
    let (psf, _) = psf_source::load(out.to_str().unwrap()).unwrap();
    let (h, w) = psf.size();
    assert!(h % 2 == 1 && w % 2 == 1 && h > 101, "{h}×{w}");
    // Its energy's centroid is the middle pixel.
    let p = psf.channel(0);
    let (mut sx, mut sy) = (0.0, 0.0);
    for (i, &v) in p.iter().enumerate() {
        sx += v as f64 * (i % w) as f64;
        sy += v as f64 * (i / w) as f64;
    }
    assert!(
        (sx - (w / 2) as f64).abs() < 1.0 && (sy - (h / 2) as f64).abs() < 1.0,
        "({sx}, {sy})"
    );
}
