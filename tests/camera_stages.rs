//! `scripts/camera_stages.py` (which stage of the camera a flow loss comes from): on a folder
//! `pins generate` wrote, its "camera" variant is the folder's own pairs again (the same seed),
//! each other variant changes the images, and every EPE it prints is the one of the flow it
//! wrote; a folder without a config is refused with the reason. Runs where Python has numpy
//! (`PINS_PYTHON`, else `python3`); says SKIPPED otherwise.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

fn python() -> Option<String> {
    common::python("camera_stages", "numpy")
}

fn script() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/camera_stages.py")
}

const PINS: &str = env!("CARGO_BIN_EXE_pins");

/// The mean endpoint error of `est` against `truth`.
fn epe(est: &Path, truth: &Path) -> f64 {
    let (e, t) = (
        pins::io::flo::read_flo(est).unwrap(),
        pins::io::flo::read_flo(truth).unwrap(),
    );
    let n = t.height() * t.width();
    let (eu, ev) = e.data().split_at(n);
    let (tu, tv) = t.data().split_at(n);
    let sum: f64 = (0..n)
        .map(|i| (((eu[i] - tu[i]) as f64).powi(2) + ((ev[i] - tv[i]) as f64).powi(2)).sqrt())
        .sum();
    sum / n as f64
}

#[test]
fn each_stage_undone_in_turn_and_the_camera_as_it_was() {
    let Some(py) = python() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let (cfg, data, work) = (
        tmp.path().join("c.json"),
        tmp.path().join("data"),
        tmp.path().join("work"),
    );
    std::fs::write(
        &cfg,
        r#"{"count": 2, "seed": 5, "scene": {"kind": "chairs", "width": 96, "height": 64}}"#,
    )
    .unwrap();
    let made = Command::new(PINS)
        .args(["generate", "--quiet", "--config"])
        .arg(&cfg)
        .arg("--out")
        .arg(&data)
        .output()
        .unwrap();
    assert!(made.status.success(), "{made:?}");

    let out = Command::new(&py)
        .arg(script())
        .args(["--pins", PINS, "--work"])
        .arg(&work)
        .arg(&data)
        .args(["--pairs", "00001"])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rows: Vec<Vec<String>> = text
        .lines()
        .filter(|l| l.starts_with("| ") && !l.starts_with("| variant"))
        .map(|l| l.split('|').map(|c| c.trim().to_string()).collect())
        .collect();
    let names: Vec<&str> = rows.iter().map(|r| r[1].as_str()).collect();
    assert_eq!(
        names,
        [
            "camera",
            "no noise",
            "delta PSF",
            "gamma 1",
            "brightness 1",
            "PSF only"
        ],
        "{text}"
    );

    let image = |dir: &Path| std::fs::read(dir.join("00001_img1.png")).unwrap();
    // The camera as it was: the folder's own pair, byte for byte.
    assert_eq!(image(&work.join("v0")), image(&data), "{text}");
    // Every other variant makes other images (v1 … v5 in the order above).
    for k in 1..=5 {
        assert_ne!(image(&work.join(format!("v{k}"))), image(&data), "v{k}");
    }
    // Each printed EPE is the one of the flow written beside it, on that variant's truth.
    for (k, row) in rows.iter().enumerate() {
        let printed: f64 = row[4].parse().unwrap();
        let measured = epe(
            &work.join(format!("v{k}-00001-w0.flo")),
            &work.join(format!("v{k}/00001_flow.flo")),
        );
        assert!((printed - measured).abs() < 1e-3, "{printed} {measured}");
    }
}

#[test]
fn a_folder_without_a_config_is_refused() {
    let Some(py) = python() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let out = Command::new(&py)
        .arg(script())
        .args(["--pins", PINS, "--work"])
        .arg(tmp.path().join("w"))
        .arg(tmp.path())
        .args(["--pairs", "00000"])
        .output()
        .unwrap();
    assert_ne!(out.status.code(), Some(0));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("config.json"), "{err}");
}
