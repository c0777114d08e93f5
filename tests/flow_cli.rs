//! End-to-end tests of `pins train`, `export`, `infer` and `eval`: exact resumption, and bad
//! input (clear error, non-zero exit, no output file).

mod common;
use common::{failed, ok, pins};

use std::fs;
use std::path::{Path, PathBuf};

use pins::dataset::{Generator, GeneratorConfig, SceneSpec, Shard};
use pins::imaging::CameraConfig;
use pins::scene::ChairsConfig;

/// A few small pairs with flow, through the ideal camera (fast).
fn tiny_dataset(dir: &Path) -> PathBuf {
    tiny_dataset_of(dir, "data", 4)
}

fn tiny_dataset_of(dir: &Path, name: &str, count: usize) -> PathBuf {
    common::tiny_dataset(dir, name, count, 3)
}

fn tiny_train_config(dir: &Path) -> PathBuf {
    let p = dir.join("train.json");
    fs::write(
        &p,
        r#"{"model": "mms-small", "steps": 4, "batch_size": 1, "crop": [64, 64], "iters": 2,
            "val_fraction": 0.25, "val_every": 2, "val_max_pairs": 1, "val_iters": 2, "checkpoint_every": 1}"#,
    )
    .unwrap();
    p
}

#[test]
fn resume_continues_exactly() {
    let tmp = tempfile::tempdir().unwrap();
    let data = tiny_dataset(tmp.path());
    let cfg = tiny_train_config(tmp.path());
    let (c, d) = (cfg.to_str().unwrap(), data.to_str().unwrap());
    let straight = tmp.path().join("straight");
    ok(&pins(&[
        "train",
        "--config",
        c,
        "--data",
        d,
        "--out",
        straight.to_str().unwrap(),
        "--quiet",
    ]));
    let chunked = tmp.path().join("chunked");
    let co = chunked.to_str().unwrap();
    ok(&pins(&[
        "train",
        "--config",
        c,
        "--data",
        d,
        "--out",
        co,
        "--stop-after",
        "2",
        "--quiet",
    ]));
    assert_eq!(common::log_steps(&chunked).len(), 2);
    // Without --resume an existing run is refused; with it, training continues at step 3.
    let err = failed(&pins(&[
        "train", "--config", c, "--data", d, "--out", co, "--quiet",
    ]));
    assert!(err.contains("--resume"), "{err}");
    ok(&pins(&[
        "train", "--config", c, "--data", d, "--out", co, "--resume", "--quiet",
    ]));
    assert_eq!(
        common::log_steps(&straight),
        common::log_steps(&chunked),
        "a resumed run must repeat the same steps"
    );
    // Same inputs, same bytes: the weights and checkpoints of the two runs are one file.
    for name in [
        "last.safetensors",
        "best.safetensors",
        "checkpoint/model-0000004.bpk",
        "checkpoint/optim-0000004.bin",
    ] {
        assert!(
            fs::read(straight.join(name)).unwrap() == fs::read(chunked.join(name)).unwrap(),
            "{name} differs between an interrupted and an uninterrupted run"
        );
    }
    // Resuming a finished run says so, with the run's last loss.
    let out = ok(&pins(&[
        "train", "--config", c, "--data", d, "--out", co, "--resume", "--quiet",
    ]));
    assert!(
        out.contains("already complete") && !out.contains("NaN"),
        "{out}"
    );
    // Another config or other data is refused on resume, naming what differs.
    let other = tmp.path().join("other.json");
    let text = fs::read_to_string(&cfg).unwrap().replace(
        r#""model": "mms-small","#,
        r#""model": "mms-small", "lr": 0.001,"#,
    );
    fs::write(&other, text).unwrap();
    let before = fs::read(chunked.join("checkpoint/state.json")).unwrap();
    let err = failed(&pins(&[
        "train",
        "--config",
        other.to_str().unwrap(),
        "--data",
        d,
        "--out",
        co,
        "--resume",
        "--quiet",
    ]));
    assert!(err.contains("lr: 0.0004 → 0.001"), "{err}");
    let data2 = tiny_dataset_of(tmp.path(), "data2", 5);
    let err = failed(&pins(&[
        "train",
        "--data",
        data2.to_str().unwrap(),
        "--out",
        co,
        "--resume",
        "--quiet",
    ]));
    assert!(err.contains("--data") && err.contains("5 pairs"), "{err}");
    assert_eq!(
        fs::read(chunked.join("checkpoint/state.json")).unwrap(),
        before,
        "a refused resume leaves the run as it was"
    );
    // Same weights: the same flow to the last bit (the files may order their tensors differently).
    let dev = burn::prelude::Device::flex();
    let (m1, c1) = pins::flow::weights::load(&straight.join("last.safetensors"), &dev).unwrap();
    let (m2, c2) = pins::flow::weights::load(&chunked.join("last.safetensors"), &dev).unwrap();
    let (a, b) =
        pins::io::read_image_pair(&data.join("00001_img1.png"), &data.join("00001_img2.png"))
            .unwrap();
    let f1 = pins::flow::infer::predict_flow(&m1, &c1, &a, &b, 2, &dev).unwrap();
    let f2 = pins::flow::infer::predict_flow(&m2, &c2, &a, &b, 2, &dev).unwrap();
    assert!(
        f1 == f2,
        "resumed weights differ from the uninterrupted run's"
    );
    assert!(straight.join("curves.png").is_file());

    // Export, infer and eval with the trained weights.
    let w = tmp.path().join("w.safetensors");
    ok(&pins(&[
        "export",
        "--run",
        straight.to_str().unwrap(),
        "--out",
        w.to_str().unwrap(),
    ]));
    // Fine-tuning from exported weights starts a new run from them.
    let tuned = tmp.path().join("tuned");
    ok(&pins(&[
        "train",
        "--config",
        c,
        "--data",
        d,
        "--out",
        tuned.to_str().unwrap(),
        "--init",
        w.to_str().unwrap(),
        "--steps",
        "1",
        "--quiet",
    ]));
    assert!(tuned.join("last.safetensors").is_file());
    // Weights of the other model size are refused.
    let big = tmp.path().join("big.safetensors");
    let big_cfg = pins::flow::model::MmsConfig::mms();
    pins::flow::weights::save(
        &big,
        &pins::flow::model::Mms::new(&big_cfg, &burn::prelude::Device::flex()),
        &big_cfg,
    )
    .unwrap();
    let err = failed(&pins(&[
        "train",
        "--config",
        c,
        "--data",
        d,
        "--out",
        tmp.path().join("x").to_str().unwrap(),
        "--init",
        big.to_str().unwrap(),
        "--quiet",
    ]));
    assert!(err.contains("mms-small"), "{err}");
    let flo = tmp.path().join("f.flo");
    let viz = tmp.path().join("f.png");
    let (i1, i2) = (data.join("00000_img1.png"), data.join("00000_img2.png"));
    ok(&pins(&[
        "infer",
        "--weights",
        w.to_str().unwrap(),
        "--img1",
        i1.to_str().unwrap(),
        "--img2",
        i2.to_str().unwrap(),
        "--out",
        flo.to_str().unwrap(),
        "--viz",
        viz.to_str().unwrap(),
        "--iters",
        "3",
    ]));
    let flow = pins::io::read_flo(&flo).unwrap();
    assert_eq!((flow.width(), flow.height()), (80, 64));
    assert!(viz.is_file());
    let report = tmp.path().join("report.json");
    let table = ok(&pins(&[
        "eval",
        "--weights",
        w.to_str().unwrap(),
        "--data",
        d,
        "--iters",
        "1,3",
        "--out",
        report.to_str().unwrap(),
    ]));
    assert!(table.contains("zero flow"), "{table}");
    let json: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(&report).unwrap()).unwrap();
    // The network at 1 and 3 iterations, then the same refined.
    let rows = json["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 4);
    let refined: Vec<bool> = rows
        .iter()
        .map(|r| r["refined"].as_bool().unwrap())
        .collect();
    assert_eq!(refined, [false, false, true, true]);
    for row in rows {
        for key in ["iters", "epe", "ae_deg", "px1", "px3", "px5", "ms_per_pair"] {
            assert!(row[key].is_number(), "{key}");
        }
    }
    assert!(json["zero_flow"]["epe"].as_f64().unwrap() > 0.0);
    assert!(report.with_extension("png").is_file());
}

#[test]
fn bad_input_fails_clearly_without_output() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let data = tiny_dataset(t);
    let (i1, i2) = (data.join("00000_img1.png"), data.join("00000_img2.png"));
    let out = t.join("out.flo");
    let o = out.to_str().unwrap();
    // A corrupt weights file.
    let corrupt = t.join("corrupt.safetensors");
    fs::write(&corrupt, b"\x10\x00\x00\x00\x00\x00\x00\x00{not json}").unwrap();
    let err = failed(&pins(&[
        "infer",
        "--weights",
        corrupt.to_str().unwrap(),
        "--img1",
        i1.to_str().unwrap(),
        "--img2",
        i2.to_str().unwrap(),
        "--out",
        o,
    ]));
    assert!(err.contains("corrupt.safetensors"), "{err}");
    assert!(!out.exists());
    // Images of different sizes.
    let small = t.join("small.png");
    pins::io::write_image(
        &small,
        &pins::Image::filled(3, 32, 40, 0.5),
        pins::io::BitDepth::Eight,
    )
    .unwrap();
    let err = failed(&pins(&[
        "infer",
        "--img1",
        i1.to_str().unwrap(),
        "--img2",
        small.to_str().unwrap(),
        "--out",
        o,
    ]));
    assert!(err.contains("small.png"), "{err}");
    assert!(!out.exists());
    // Unreadable image.
    let err = failed(&pins(&[
        "infer",
        "--img1",
        "/no/such.png",
        "--img2",
        i2.to_str().unwrap(),
        "--out",
        o,
    ]));
    assert!(err.contains("such.png"), "{err}");
    assert!(!out.exists());
    // Empty and malformed dataset folders.
    let empty = t.join("empty");
    fs::create_dir_all(&empty).unwrap();
    let report = t.join("r.json");
    let err = failed(&pins(&[
        "eval",
        "--data",
        empty.to_str().unwrap(),
        "--out",
        report.to_str().unwrap(),
    ]));
    assert!(err.contains("no image pairs"), "{err}");
    let broken = t.join("broken");
    fs::create_dir_all(&broken).unwrap();
    fs::copy(&i1, broken.join("00000_img1.png")).unwrap();
    fs::copy(&i2, broken.join("00000_img2.png")).unwrap();
    fs::write(broken.join("00000_flow.flo"), b"PIEH").unwrap();
    let err = failed(&pins(&[
        "eval",
        "--data",
        broken.to_str().unwrap(),
        "--out",
        report.to_str().unwrap(),
    ]));
    assert!(err.contains("00000_flow.flo"), "{err}");
    assert!(!report.exists());
    // Training: bad config values and a missing dataset.
    let bad = t.join("bad.json");
    fs::write(&bad, r#"{"crop": [100, 64]}"#).unwrap();
    let err = failed(&pins(&[
        "train",
        "--config",
        bad.to_str().unwrap(),
        "--data",
        data.to_str().unwrap(),
        "--out",
        t.join("run").to_str().unwrap(),
    ]));
    assert!(err.contains("crop"), "{err}");
    let err = failed(&pins(&[
        "train",
        "--data",
        "/no/such/data",
        "--out",
        t.join("run").to_str().unwrap(),
    ]));
    assert!(err.contains("/no/such/data"), "{err}");
    assert!(!t.join("run").exists());
    // A dataset whose every flow vector is unknown: refused before any work or output.
    let unknown = t.join("unknown");
    fs::create_dir_all(&unknown).unwrap();
    for k in 0..2 {
        fs::copy(&i1, unknown.join(format!("0000{k}_img1.png"))).unwrap();
        fs::copy(&i2, unknown.join(format!("0000{k}_img2.png"))).unwrap();
        let nan = pins::Flow::from_vec(64, 80, vec![f32::NAN; 2 * 64 * 80]).unwrap();
        pins::io::write_flo(&unknown.join(format!("0000{k}_flow.flo")), &nan).unwrap();
    }
    let err = failed(&pins(&[
        "eval",
        "--data",
        unknown.to_str().unwrap(),
        "--out",
        report.to_str().unwrap(),
    ]));
    assert!(err.contains("known vector"), "{err}");
    assert!(!report.exists() && !report.with_extension("png").exists());
    let err = failed(&pins(&[
        "train",
        "--data",
        unknown.to_str().unwrap(),
        "--out",
        t.join("run").to_str().unwrap(),
    ]));
    assert!(err.contains("known vector"), "{err}");
    assert!(
        !t.join("run").exists(),
        "no run folder for a refused dataset"
    );
}

#[test]
fn the_shipped_weights_recover_most_of_the_motion_of_unseen_metalens_pairs() {
    let tmp = tempfile::tempdir().unwrap();
    let data = tmp.path().join("data");
    // Pairs the weights never saw (another seed), through the default metalens camera.
    let cfg = GeneratorConfig {
        count: 3,
        seed: 777,
        scene: SceneSpec::Chairs(ChairsConfig {
            width: 256,
            height: 192,
            ..ChairsConfig::default()
        }),
        camera: CameraConfig::default(),
        save_clean: false,
    };
    Generator::new(cfg)
        .unwrap()
        .run(&data, Shard::ALL, false)
        .unwrap();
    let report = tmp.path().join("report.json");
    ok(&pins(&[
        "eval",
        "--data",
        data.to_str().unwrap(),
        "--iters",
        "6",
        "--out",
        report.to_str().unwrap(),
    ]));
    let json: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(&report).unwrap()).unwrap();
    let (epe, zero) = (
        json["rows"][0]["epe"].as_f64().unwrap(),
        json["zero_flow"]["epe"].as_f64().unwrap(),
    );
    assert!(
        epe < 0.6 * zero,
        "shipped weights: EPE {epe} against {zero} for zero flow"
    );
}

/// `pins infer --frames --scale`: the network runs at another size, the flow comes back at the
/// frames' size and in their pixels; a scale outside (0, 4] is refused before any output.
#[test]
fn infer_at_another_scale_gives_flow_at_the_frames_size() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let data = tiny_dataset(t);
    let frames = t.join("frames");
    fs::create_dir_all(&frames).unwrap();
    fs::copy(data.join("00000_img1.png"), frames.join("a.png")).unwrap();
    fs::copy(data.join("00000_img2.png"), frames.join("b.png")).unwrap();
    let truth = pins::io::read_flow(&data.join("00000_flow.flo")).unwrap();
    let (f, w, h) = (frames.to_str().unwrap(), truth.width(), truth.height());
    let epe = |flow: &pins::Flow| {
        let (u, v, tu, tv) = (flow.u(), flow.v(), truth.u(), truth.v());
        let n = u.len() as f64;
        (0..u.len())
            .map(|i| ((u[i] - tu[i]) as f64).hypot((v[i] - tv[i]) as f64))
            .sum::<f64>()
            / n
    };
    let zero = epe(&pins::Flow::zeros(h, w));
    let mut flows = Vec::new();
    for scale in ["1", "1.5", "0.75"] {
        let out = t.join(format!("out{scale}"));
        ok(&pins(&[
            "infer",
            "--weights",
            "mms-small",
            "--frames",
            f,
            "--out",
            out.to_str().unwrap(),
            "--iters",
            "4",
            "--refine",
            "none",
            "--start",
            "zero",
            "--scale",
            scale,
        ]));
        let flow = pins::io::read_flow(&out.join("a.flo")).unwrap();
        assert_eq!((flow.width(), flow.height()), (w, h), "scale {scale}");
        assert!(flow.u().iter().chain(flow.v()).all(|x| x.is_finite()));
        let e = epe(&flow);
        assert!(
            e < 0.7 * zero,
            "scale {scale}: EPE {e} against zero flow's {zero}"
        );
        flows.push(flow);
    }
    assert_ne!(
        flows[0].u(),
        flows[1].u(),
        "--scale 1.5 ran at another size"
    );
    for bad in ["0", "5", "NaN", "-1"] {
        let out = t.join("bad");
        let err = failed(&pins(&[
            "infer",
            "--frames",
            f,
            "--out",
            out.to_str().unwrap(),
            "--scale",
            bad,
        ]));
        assert!(err.contains("--scale"), "{bad}: {err}");
        assert!(!out.exists(), "{bad}: no output");
    }
}

#[test]
fn average_writes_the_mean_of_one_network_and_refuses_others() {
    use burn::prelude::Device;
    use pins::flow::model::{Mms, MmsConfig};
    let tmp = tempfile::tempdir().unwrap();
    let save = |name: &str, cfg: &MmsConfig, seed: u64| {
        let dev = Device::flex();
        dev.seed(seed);
        let p = tmp.path().join(name);
        pins::flow::weights::save(&p, &Mms::new(cfg, &dev), cfg).unwrap();
        p
    };
    let small = MmsConfig::mms_small();
    let (a, b) = (
        save("a.safetensors", &small, 1),
        save("b.safetensors", &small, 2),
    );
    let avg = tmp.path().join("avg.safetensors");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let out = ok(&pins(&["average", &s(&a), &s(&b), "--out", &s(&avg)]));
    assert!(out.contains("2 files"), "{out}");
    let (_, cfg) = pins::flow::weights::load(&avg, &Device::flex()).unwrap();
    assert_eq!(cfg, small);
    // Another network, or a single file: refused, nothing written.
    let big = save("big.safetensors", &MmsConfig::mms(), 3);
    let bad = tmp.path().join("bad.safetensors");
    let err = failed(&pins(&["average", &s(&a), &s(&big), "--out", &s(&bad)]));
    assert!(err.contains("only weights of one network"), "{err}");
    failed(&pins(&["average", &s(&a), "--out", &s(&bad)]));
    assert!(!bad.exists(), "a refused average left a file");
}
