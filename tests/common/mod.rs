//! Helpers shared by the command-line tests: run the `pins` binary and check its outcome.
#![allow(dead_code)]

use std::process::{Command, Output};

/// Runs `pins` with `args`.
pub fn pins(args: &[&str]) -> Output {
    pins_with_threads(args, None)
}

/// Runs `pins` with `args`, optionally with `RAYON_NUM_THREADS` set.
pub fn pins_with_threads(args: &[&str], threads: Option<usize>) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_pins"));
    cmd.args(args);
    if let Some(t) = threads {
        cmd.env("RAYON_NUM_THREADS", t.to_string());
    }
    cmd.output().expect("run pins")
}

/// Asserts success; returns stdout.
pub fn ok(out: &Output) -> String {
    assert!(
        out.status.success(),
        "pins failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Asserts failure; returns stderr.
pub fn failed(out: &Output) -> String {
    assert!(
        !out.status.success(),
        "pins should fail: {}",
        String::from_utf8_lossy(&out.stdout)
    );
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A small generated dataset (`count` chairs pairs of 80×64 with flow, through the ideal
/// camera: fast) in `dir/name`.
pub fn tiny_dataset(
    dir: &std::path::Path,
    name: &str,
    count: usize,
    seed: u64,
) -> std::path::PathBuf {
    use pins::dataset::{Generator, GeneratorConfig, SceneSpec, Shard};
    let out = dir.join(name);
    let cfg = GeneratorConfig {
        count,
        seed,
        scene: SceneSpec::Chairs(pins::scene::ChairsConfig {
            width: 80,
            height: 64,
            sprites: [1, 2],
            supersample: 1,
            ..pins::scene::ChairsConfig::default()
        }),
        camera: pins::imaging::CameraConfig::ideal(),
        save_clean: false,
    };
    Generator::new(cfg)
        .expect("generator")
        .run(&out, Shard::ALL, false)
        .expect("generate");
    out
}

/// Renders a 160×120 clip of `frames` frames through the default camera: one disc of radius
/// 10 on a line between two points (fractions of the frame), with its exact flow and truth.
pub fn render_disc_line(
    dir: &std::path::Path,
    seed: u64,
    frames: usize,
    from: [f64; 2],
    to: [f64; 2],
) -> pins::scene::truth::Truth {
    use pins::dataset::sequence::{SequenceConfig, render_sequence};
    use pins::scene::trajectory::{ObjectSpec, PathKind, TrajectoryConfig};
    let cfg = SequenceConfig {
        scene: TrajectoryConfig {
            width: 160,
            height: 120,
            frames,
            seed,
            objects: vec![ObjectSpec {
                path: PathKind::Line,
                radius: 10.0,
                from,
                to,
                ..ObjectSpec::default()
            }],
            ..TrajectoryConfig::default()
        },
        ..SequenceConfig::default()
    };
    render_sequence(&cfg, dir).expect("render the clip")
}

/// Every f32 tensor of a safetensors file, by name (sorted).
pub fn safetensors_f32(path: &std::path::Path) -> Vec<(String, Vec<f32>)> {
    let bytes = std::fs::read(path).unwrap();
    let n = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
    let header: serde_json::Value = serde_json::from_slice(&bytes[8..8 + n]).unwrap();
    let data = &bytes[8 + n..];
    let mut out: Vec<(String, Vec<f32>)> = header
        .as_object()
        .unwrap()
        .iter()
        .filter(|(k, v)| *k != "__metadata__" && v["dtype"] == "F32")
        .map(|(k, v)| {
            let (a, b) = (
                v["data_offsets"][0].as_u64().unwrap() as usize,
                v["data_offsets"][1].as_u64().unwrap() as usize,
            );
            let vals = data[a..b]
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
                .collect();
            (k.clone(), vals)
        })
        .collect();
    out.sort_by(|a, b| a.0.cmp(&b.0));
    out
}

/// Column `col` of a training run's `log.csv` (step, lr, loss, EPE, ...), one value per step.
pub fn log_column(run: &std::path::Path, col: usize) -> Vec<f64> {
    std::fs::read_to_string(run.join("log.csv"))
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(col).unwrap().parse().unwrap())
        .collect()
}

/// The first four columns of each row of a training run's `log.csv` (step, lr, loss, EPE) as
/// written: two runs that took the same steps have equal rows.
pub fn log_steps(run: &std::path::Path) -> Vec<String> {
    std::fs::read_to_string(run.join("log.csv"))
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').take(4).collect::<Vec<_>>().join(","))
        .collect()
}

/// `../shared/data` (real pairs written by others), or `None` with a message when this
/// checkout has none beside it.
pub fn shared_data() -> Option<std::path::PathBuf> {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
    if p.is_dir() {
        Some(p)
    } else {
        eprintln!("skipping: ../shared/data not found");
        None
    }
}

/// `pins train --config CFG --data DATA --out OUT --quiet EXTRA…`, with `threads` rayon threads
/// when given.
pub fn train(
    cfg: &std::path::Path,
    data: &std::path::Path,
    out: &std::path::Path,
    extra: &[&str],
    threads: Option<usize>,
) -> Output {
    let path = |p: &std::path::Path| p.to_str().expect("a UTF-8 path").to_string();
    let (cfg, data, out) = (path(cfg), path(data), path(out));
    let mut args = vec![
        "train", "--config", &cfg, "--data", &data, "--out", &out, "--quiet",
    ];
    args.extend_from_slice(extra);
    pins_with_threads(&args, threads)
}

/// The Python interpreter of the script tests (`PINS_PYTHON`, else `python3`) when it can
/// `import modules` (e.g. "numpy, PIL"); otherwise says SKIPPED for `test` and gives `None`.
pub fn python(test: &str, modules: &str) -> Option<String> {
    let py = std::env::var("PINS_PYTHON").unwrap_or_else(|_| "python3".into());
    let found = Command::new(&py)
        .args(["-c", &format!("import {modules}")])
        .output()
        .is_ok_and(|o| o.status.success());
    if !found {
        eprintln!("SKIPPED {test}: {py} cannot import {modules} (set PINS_PYTHON)");
    }
    found.then_some(py)
}
