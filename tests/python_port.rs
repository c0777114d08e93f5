//! The network outside pins (`python/pins_mms`): the PyTorch module and its ONNX export, run by
//! ONNX Runtime, give `pins infer`'s network flow (`--start zero --refine none`) on real pairs, at
//! 4 and 12 iterations, for the shipped weights, a random full-size `mms` and a config of
//! neither size; bad weights files are refused with the reason and leave no output.
//!
//! Runs where Python has torch, onnx, onnxscript, onnxruntime, numpy and Pillow (`PINS_PYTHON`,
//! else `python3`; `.ci/run` installs them) and says SKIPPED with the reason elsewhere.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use pins::flow::model::{Mms, MmsConfig, NormKind};
use pins::flow::weights;
use pins::io::{BitDepth, read_flo, read_image, write_image};
use pins::{Flow, Image};

use burn::prelude::*;
use common::{ok, pins, shared_data};

const MODULES: [&str; 6] = ["torch", "onnx", "onnxscript", "onnxruntime", "numpy", "PIL"];

/// The Python to run, or `None` (with SKIPPED and the reason) where it lacks a module.
fn python() -> Option<String> {
    let py = std::env::var("PINS_PYTHON").unwrap_or_else(|_| "python3".into());
    let mut missing = Vec::new();
    for m in MODULES {
        let found = Command::new(&py)
            .args(["-c", &format!("import {m}")])
            .output()
            .is_ok_and(|o| o.status.success());
        if !found {
            missing.push(m);
        }
    }
    if missing.is_empty() {
        Some(py)
    } else {
        eprintln!(
            "SKIPPED python_port: {py} lacks {} (pip install -e python[onnx], or set PINS_PYTHON)",
            missing.join(", ")
        );
        None
    }
}

fn python_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("python")
}

/// `python -m pins_mms ARGS` from the repository's `python/`.
fn pins_mms(py: &str, args: &[&str]) -> Output {
    Command::new(py)
        .args(["-m", "pins_mms"])
        .args(args)
        .env("PYTHONPATH", python_dir())
        .output()
        .expect("run python")
}

/// Runs the jobs of `python/tests/flows.py` in one process.
fn run_jobs(py: &str, dir: &Path, jobs: &serde_json::Value) {
    let list = dir.join("jobs.json");
    std::fs::write(&list, jobs.to_string()).unwrap();
    let out = Command::new(py)
        .arg(python_dir().join("tests/flows.py"))
        .arg(&list)
        .output()
        .expect("run python");
    assert!(
        out.status.success(),
        "flows.py failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    eprint!("{}", String::from_utf8_lossy(&out.stdout));
}

/// A real pair: name, first and second image.
struct Pair {
    name: String,
    img1: PathBuf,
    img2: PathBuf,
}

/// The real pairs of `../shared/data` where it exists, and always a photograph shipped in the
/// repository with a second frame moved by (3, 2) px, both cropped from it.
fn real_pairs(dir: &Path) -> Vec<Pair> {
    let photo = read_image(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("datasets/photos/bench/chelsea.png"),
    )
    .unwrap();
    let (c, h, w) = photo.shape();
    let crop = |dx: usize, dy: usize| {
        let (ch, cw) = (h - 2, w - 3);
        let mut out = Image::zeros(c, ch, cw);
        for k in 0..c {
            for y in 0..ch {
                for x in 0..cw {
                    out.set(k, y, x, photo.get(k, y + dy, x + dx));
                }
            }
        }
        out
    };
    let (a, b) = (dir.join("photo1.png"), dir.join("photo2.png"));
    write_image(&a, &crop(3, 2), BitDepth::Eight).unwrap();
    write_image(&b, &crop(0, 0), BitDepth::Eight).unwrap();
    let mut pairs = vec![Pair {
        name: "photo".into(),
        img1: a,
        img2: b,
    }];
    if let Some(data) = shared_data() {
        for (name, a, b) in [
            (
                "middlebury",
                "middlebury_rubberwhale/frame10.png",
                "middlebury_rubberwhale/frame11.png",
            ),
            (
                "kitti",
                "kitti2015_000000/frame1.png",
                "kitti2015_000000/frame2.png",
            ),
            (
                "sintel",
                "sintel_alley1/frame_0001.png",
                "sintel_alley1/frame_0002.png",
            ),
        ] {
            pairs.push(Pair {
                name: name.into(),
                img1: data.join(a),
                img2: data.join(b),
            });
        }
    }
    pairs
}

fn pins_flow(weights: &str, pair: &Pair, iters: usize, out: &Path) {
    ok(&pins(&[
        "infer",
        "--weights",
        weights,
        "--img1",
        pair.img1.to_str().unwrap(),
        "--img2",
        pair.img2.to_str().unwrap(),
        "--iters",
        &iters.to_string(),
        "--start",
        "zero",
        "--refine",
        "none",
        "--out",
        out.to_str().unwrap(),
    ]));
}

/// The endpoint differences of two flows: mean, 99.9th percentile and max, and the reference's
/// mean length.
fn difference(a: &Flow, b: &Flow) -> (f64, f64, f64, f64) {
    assert_eq!(
        (a.height(), a.width()),
        (b.height(), b.width()),
        "flow sizes"
    );
    let mut d = Vec::with_capacity(a.height() * a.width());
    let mut len = 0.0;
    for y in 0..a.height() {
        for x in 0..a.width() {
            let ((u1, v1), (u2, v2)) = (a.get(y, x), b.get(y, x));
            d.push(f64::from(u1 - u2).hypot(f64::from(v1 - v2)));
            len += f64::from(u2).hypot(f64::from(v2));
        }
    }
    let n = d.len() as f64;
    let mean = d.iter().sum::<f64>() / n;
    d.sort_by(f64::total_cmp);
    let p999 = d[((n * 0.999) as usize).min(d.len() - 1)];
    (mean, p999, d[d.len() - 1], len / n)
}

/// The comparison of one flow against pins's: the endpoint difference averages at most 1e-3 px
/// (measured: up to 5e-5 px); the largest, at a few pixels where float32 arithmetic in any order
/// is ~1e-3 px from a float64 run (KITTI at 12 iterations), stays under 1e-2 px.
fn assert_matches(what: &str, got: &Path, pins: &Path) {
    let (got, want) = (read_flo(got).unwrap(), read_flo(pins).unwrap());
    let (mean, p999, max, len) = difference(&got, &want);
    eprintln!(
        "{what}: endpoint difference from pins mean {mean:.2e} px, 99.9 % {p999:.2e} px, max \
         {max:.2e} px (flow mean length {len:.2} px)"
    );
    assert!(
        mean <= 1e-3 && max <= 1e-2,
        "{what}: mean {mean:.2e} px, max {max:.2e} px from pins"
    );
}

#[test]
fn pytorch_and_onnx_give_pins_network_flow_on_real_pairs() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let pairs = real_pairs(d);
    let weights =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("datasets/weights/mms-small-real.safetensors");
    let weights = weights.to_str().unwrap();
    // The ONNX graph at 12 iterations (its export takes a minute or two on 2 cores; at 4
    // iterations it is the same graph, shorter).
    let onnx = d.join("mms12.onnx");
    let mut jobs = vec![serde_json::json!({"export": weights, "iters": 12, "out": onnx})];
    let (mut checks, mut floors) = (Vec::new(), Vec::new());
    for iters in [4, 12] {
        for p in &pairs {
            let reference = d.join(format!("{}_{iters}_pins.flo", p.name));
            pins_flow(weights, p, iters, &reference);
            let mut kinds = vec![("torch", "weights", weights.to_string())];
            if iters == 12 {
                kinds.push(("onnx", "onnx", onnx.to_str().unwrap().to_string()));
            }
            for (kind, key, model) in kinds {
                let out = d.join(format!("{}_{iters}_{kind}.flo", p.name));
                jobs.push(serde_json::json!({
                    key: model, "iters": iters, "img1": p.img1, "img2": p.img2, "out": out,
                }));
                let what = format!("{} {kind} at {iters} iterations", p.name);
                checks.push((what, out, reference.clone()));
            }
            if iters == 12 {
                let out = d.join(format!("{}_{iters}_f64.flo", p.name));
                jobs.push(serde_json::json!({
                    "weights": weights, "float64": true, "iters": iters, "img1": p.img1,
                    "img2": p.img2, "out": out,
                }));
                floors.push((
                    p.name.clone(),
                    out,
                    reference,
                    d.join(format!("{}_12_torch.flo", p.name)),
                ));
            }
        }
    }
    run_jobs(&py, d, &serde_json::Value::Array(jobs));
    for (what, got, reference) in checks {
        assert_matches(&what, &got, &reference);
    }
    // Against a float64 run: how far float32 arithmetic alone takes each form from exact.
    for (name, f64_flow, pins_flow, torch_flow) in floors {
        let exact = read_flo(&f64_flow).unwrap();
        for (who, path) in [("pins", pins_flow), ("torch float32", torch_flow)] {
            let (mean, p999, max, _) = difference(&read_flo(&path).unwrap(), &exact);
            eprintln!(
                "{name} {who} at 12 iterations against float64: mean {mean:.2e} px, 99.9 % \
                 {p999:.2e} px, max {max:.2e} px"
            );
            assert!(
                mean <= 1e-3 && max <= 1e-2,
                "{name} {who}: {mean:.2e} / {max:.2e}"
            );
        }
    }
}

/// A config of neither named size: group norm in both encoders, 3 levels of radius 3, two
/// dilations.
fn other_config() -> MmsConfig {
    MmsConfig {
        name: "other".into(),
        encoder_dims: [16, 24, 32],
        feature_dim: 48,
        hidden_dim: 32,
        context_dim: 16,
        motion_dims: [32, 16, 24],
        head_dim: 32,
        dilations: vec![2, 4],
        corr_levels: 3,
        corr_radius: 3,
        iters: 6,
        feature_norm: NormKind::Group,
        context_norm: NormKind::Group,
    }
}

#[test]
fn any_weights_file_loads_by_its_metadata() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let pair = &real_pairs(d)[0];
    for (name, cfg) in [("mms", MmsConfig::mms()), ("other", other_config())] {
        let file = d.join(format!("{name}.safetensors"));
        weights::save(&file, &Mms::new(&cfg, &Device::flex()), &cfg).unwrap();
        let file = file.to_str().unwrap();
        let (want, got) = (
            d.join(format!("{name}_pins.flo")),
            d.join(format!("{name}.flo")),
        );
        pins_flow(file, pair, 4, &want);
        let out = pins_mms(
            &py,
            &[
                "infer",
                "--weights",
                file,
                "--img1",
                pair.img1.to_str().unwrap(),
                "--img2",
                pair.img2.to_str().unwrap(),
                "--iters",
                "4",
                "--out",
                got.to_str().unwrap(),
            ],
        );
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert_matches(&format!("random {name} at 4 iterations"), &got, &want);
    }
}

#[test]
fn bad_weights_files_are_refused_with_the_reason() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let pair = &real_pairs(d)[0];
    let shipped = std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("datasets/weights/mms-small-real.safetensors"),
    )
    .unwrap();
    // Another model's tensors under the full-size config: the metadata says mms.
    let small = serde_json::to_string(&MmsConfig::mms_small()).unwrap();
    let full = serde_json::to_string(&MmsConfig::mms()).unwrap();
    let header_len = u64::from_le_bytes(shipped[..8].try_into().unwrap()) as usize;
    let header = String::from_utf8(shipped[8..8 + header_len].to_vec()).unwrap();
    let escaped = |s: &str| serde_json::to_string(s).unwrap();
    assert!(header.contains(&escaped(&small)), "the shipped config");
    let header = header.replace(&escaped(&small), &escaped(&full));
    let mut other = (header.len() as u64).to_le_bytes().to_vec();
    other.extend_from_slice(header.as_bytes());
    other.extend_from_slice(&shipped[8 + header_len..]);
    // A safetensors file without pins's metadata.
    let plain = b"{\"x\":{\"dtype\":\"F32\",\"shape\":[1],\"data_offsets\":[0,4]}}";
    let mut bare = (plain.len() as u64).to_le_bytes().to_vec();
    bare.extend_from_slice(plain);
    bare.extend_from_slice(&[0; 4]);
    for (name, bytes, reason) in [
        ("other.safetensors", other, "do not fit the mms config"),
        ("bare.safetensors", bare, "not a pins weights file"),
        (
            "truncated.safetensors",
            shipped[..shipped.len() / 2].to_vec(),
            "truncated",
        ),
        (
            "text.safetensors",
            b"weights".to_vec(),
            "not a safetensors file",
        ),
    ] {
        let file = d.join(name);
        std::fs::write(&file, bytes).unwrap();
        let out_flo = d.join(format!("{name}.flo"));
        let out = pins_mms(
            &py,
            &[
                "infer",
                "--weights",
                file.to_str().unwrap(),
                "--img1",
                pair.img1.to_str().unwrap(),
                "--img2",
                pair.img2.to_str().unwrap(),
                "--out",
                out_flo.to_str().unwrap(),
            ],
        );
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{name}: {err}");
        assert!(err.contains(reason), "{name}: {err}");
        assert!(!err.contains("Traceback"), "{name}: {err}");
        assert!(!out_flo.exists(), "{name}: a partial output");
        let onnx = d.join(format!("{name}.onnx"));
        let out = pins_mms(
            &py,
            &[
                "export",
                file.to_str().unwrap(),
                "--out",
                onnx.to_str().unwrap(),
            ],
        );
        assert_eq!(out.status.code(), Some(2), "{name}: export");
        assert!(!onnx.exists(), "{name}: a partial ONNX file");
    }
    // Images of two sizes, and an output that is not .flo.
    let out = pins_mms(
        &py,
        &[
            "infer",
            "--img1",
            pair.img1.to_str().unwrap(),
            "--img2",
            Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("datasets/photos/bench/camera.png")
                .to_str()
                .unwrap(),
            "--out",
            d.join("sizes.flo").to_str().unwrap(),
        ],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("second image"), "{err}");
    assert!(!d.join("sizes.flo").exists());
}
