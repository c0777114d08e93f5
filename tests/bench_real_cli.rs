//! End-to-end tests of `pins bench-real` on tiny configs: every set, camera, method and pair is
//! reported with finite numbers, the zero-flow EPE is the mean ground-truth speed over the known
//! pixels (KITTI's sparse valid bit and Middlebury's unknown flow masked), a missing set is
//! reported and skipped, and bad input is a clear error with no output.

mod common;
use common::{failed, ok, pins, shared_data};

use std::fs;
use std::path::{Path, PathBuf};

use serde_json::Value;

/// A generated chairs set that needs no data, a missing set, and the FlyingChairs crops when
/// `../shared/data` is there.
fn tiny_config(dir: &Path) -> PathBuf {
    let mut sets = vec![
        r#"{"name": "tiny", "scene": {"kind": "chairs", "width": 64, "height": 48, "sprites": [1, 2], "supersample": 1}, "count": 2, "seed": 5}"#.to_string(),
        r#"{"name": "gone", "scene": {"kind": "dataset", "path": "no_such_folder", "layout": "chairs"}}"#.to_string(),
    ];
    if let Some(d) = shared_data() {
        sets.push(format!(
            r#"{{"name": "crops", "scene": {{"kind": "dataset", "path": "{}", "layout": "chairs"}}}}"#,
            d.join("flyingchairs_crops").display()
        ));
    }
    let p = dir.join("bench.json");
    fs::write(
        &p,
        format!(r#"{{"iters": [1, 2], "sets": [{}]}}"#, sets.join(", ")),
    )
    .unwrap();
    p
}

fn read_report(out: &Path) -> Value {
    serde_json::from_str(&fs::read_to_string(out.join("report.json")).unwrap()).unwrap()
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

/// The mean |flow| over the known vectors of a flow file, computed here.
fn mean_gt(path: &Path) -> (u64, f64) {
    let flow = pins::io::read_flow(path).unwrap();
    let (mut n, mut sum) = (0u64, 0.0f64);
    for (u, v) in flow.u().iter().zip(flow.v()) {
        if u.is_finite() && v.is_finite() {
            n += 1;
            let (u, v) = (*u as f64, *v as f64);
            sum += (u * u + v * v).sqrt();
        }
    }
    (n, sum / n.max(1) as f64)
}

/// Every run has the MMS rows (the network's, then the refined flow's), the peers (when they
/// ran) and the zero flow, over the set and each pair, with finite numbers in range; the zero
/// flow is the mean |gt| of the flow files.
fn check_runs(r: &Value, sets: &[&str], cameras: &[&str], iters: &[u64]) {
    let runs = r["runs"].as_array().unwrap();
    assert_eq!(runs.len(), sets.len() * cameras.len());
    let peers = r["peers"]["ran"].as_bool().unwrap();
    let mut expected: Vec<String> = iters.iter().map(|n| format!("mms-small, {n} it")).collect();
    expected.extend(
        iters
            .iter()
            .map(|n| format!("mms-small + variational, {n} it")),
    );
    if peers {
        for m in [
            "OpenCV DIS medium",
            "OpenCV DIS fast",
            "OpenCV DIS ultrafast",
            "OpenCV Farneback",
        ] {
            expected.push(m.into());
        }
    }
    expected.push("zero flow".into());
    let label = |m: &Value| match m["iters"].as_u64() {
        Some(n) => format!("{}, {n} it", m["method"].as_str().unwrap()),
        None => m["method"].as_str().unwrap().to_string(),
    };
    let check_rows = |rows: &Value, mean: f64, pixels: u64, what: &str| {
        let rows = rows.as_array().unwrap();
        assert_eq!(
            rows.iter().map(label).collect::<Vec<_>>(),
            expected,
            "{what}"
        );
        for m in rows {
            for k in ["epe", "ae_deg", "ms_per_pair"] {
                assert!(f(&m[k]).is_finite() && f(&m[k]) >= 0.0, "{what} {k}: {m}");
            }
            let (p1, p3, p5) = (f(&m["px1"]), f(&m["px3"]), f(&m["px5"]));
            assert!(
                (0.0..=1.0).contains(&p1) && p1 <= p3 && p3 <= p5 && p5 <= 1.0,
                "{m}"
            );
            // The speed classes (Rust's and the peers' script's) split the known pixels, and
            // their EPEs weighed by their pixels are the whole EPE.
            let b = &m["by_speed"];
            let n: Vec<u64> = (0..3).map(|c| b["pixels"][c].as_u64().unwrap()).collect();
            assert_eq!(n.iter().sum::<u64>(), pixels, "{what}: {m}");
            let whole: f64 = (0..3).map(|c| f(&b["epe"][c]) * n[c] as f64).sum();
            let epe = f(&m["epe"]);
            assert!(
                (whole / pixels as f64 - epe).abs() <= 1e-6 * (1.0 + epe),
                "{what}: {m}"
            );
        }
        let zero = rows.last().unwrap();
        assert!(
            (f(&zero["epe"]) - mean).abs() <= 1e-9 * (1.0 + mean),
            "{what}: zero-flow EPE {} against mean |gt| {mean}",
            zero["epe"]
        );
    };
    for set in sets {
        for cam in cameras {
            let run = runs
                .iter()
                .find(|x| x["set"] == *set && x["camera"] == *cam)
                .unwrap_or_else(|| panic!("no run {set} / {cam}"));
            let data = PathBuf::from(run["data"].as_str().unwrap());
            let pairs = run["per_pair"].as_array().unwrap();
            assert_eq!(pairs.len() as u64, run["pairs"].as_u64().unwrap());
            let (mut n_all, mut sum_all) = (0u64, 0.0);
            for p in pairs {
                let name = p["name"].as_str().unwrap();
                let (n, mean) = mean_gt(&data.join(format!("{name}_flow.flo")));
                assert!(n > 0);
                assert_eq!(p["pixels"].as_u64().unwrap(), n, "{set}/{cam}/{name}");
                assert!((f(&p["mean_gt"]) - mean).abs() <= 1e-9 * (1.0 + mean));
                check_rows(&p["methods"], mean, n, &format!("{set}/{cam}/{name}"));
                // The set's MMS scores are the pixel-weighted means of its pairs'.
                n_all += n;
                sum_all += n as f64 * f(&p["methods"][0]["epe"]);
            }
            assert_eq!(run["pixels"].as_u64().unwrap(), n_all);
            let mms = f(&run["methods"][0]["epe"]);
            assert!((mms - sum_all / n_all as f64).abs() < 1e-9 * (1.0 + mms));
            check_rows(
                &run["methods"],
                f(&run["mean_gt"]),
                n_all,
                &format!("{set}/{cam}"),
            );
        }
    }
    let summary = r["summary"].as_array().unwrap();
    assert_eq!(summary.len(), cameras.len() * expected.len());
    for s in summary {
        assert_eq!(s["sets"].as_u64().unwrap(), sets.len() as u64);
        assert!(f(&s["scores"]["epe"]).is_finite());
    }
}

#[test]
fn tiny_benchmark_reports_every_set_method_and_pair() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = tiny_config(dir.path());
    let out = dir.path().join("bench");
    let run = pins(&[
        "bench-real",
        "--config",
        cfg.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let stdout = ok(&run);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains("set gone: skipped") && stderr.contains("no_such_folder"),
        "{stderr}"
    );
    for f in [
        "report.json",
        "report.md",
        "epe_vs_ms_clean.png",
        "epe_vs_ms_camera.png",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
        assert!(stdout.contains(f), "{stdout}");
    }
    let r = read_report(&out);
    let mut sets = vec!["tiny"];
    if shared_data().is_some() {
        sets.push("crops");
    }
    check_runs(&r, &sets, &["clean", "camera"], &[1, 2]);
    assert_eq!(r["skipped"][0]["set"], "gone");
    if !r["peers"]["ran"].as_bool().unwrap() {
        eprintln!(
            "peers did not run: {}",
            r["peers"]["skipped_because"].as_str().unwrap()
        );
    }
    let md = fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("set **gone** skipped"), "{md}");
    // The verdict section is there and says why it has no tables: the tiny run measures 1 and 2
    // iterations, not 12 against DIS nor 4/12/16.
    assert_eq!(r["start"], "coarse");
    assert!(md.contains("from a coarse start) on"), "{md}");
    assert!(
        md.contains("## Against DIS medium, and across iterations"),
        "{md}"
    );
    assert!(md.contains("No comparison with OpenCV DIS medium"), "{md}");
    assert!(md.contains("No iteration ratios"), "{md}");
    // The EPE by speed: a column per camera and Sintel class, a row per method.
    assert!(
        md.contains("## EPE by ground-truth speed (px), all known pixels"),
        "{md}"
    );
    for col in ["| clean s0-10 (", "| camera s10-40 (", "| camera s40+ ("] {
        assert!(md.contains(col), "{col}: {md}");
    }
    assert!(md.contains("| mms-small 2 it |"), "{md}");
    for set in &sets {
        for cam in ["clean", "camera"] {
            assert!(md.contains(&format!("### {set}, {cam}: ")), "{set} {cam}");
            assert!(md.contains(&format!("| {set} | {cam} |")), "{set} {cam}");
        }
    }
    // A second run reuses the generated pairs and gives the same scores.
    let again = pins(&[
        "bench-real",
        "--config",
        cfg.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--no-peers",
        "--iters",
        "2",
    ]);
    ok(&again);
    let r2 = read_report(&out);
    check_runs(&r2, &sets, &["clean", "camera"], &[2]);
    assert_eq!(r2["peers"]["skipped_because"], "--no-peers");
    assert_eq!(r2["runs"][0]["per_pair"][0]["methods"][0]["epe"], {
        let run = &r["runs"][0]["per_pair"][0]["methods"];
        run.as_array()
            .unwrap()
            .iter()
            .find(|m| m["iters"] == 2)
            .unwrap()["epe"]
            .clone()
    });
}

/// Middlebury's unknown flow (≥ 1e9) and KITTI's sparse valid bit: only known pixels count.
#[test]
fn real_sets_mask_unknown_flow() {
    let Some(data) = shared_data() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("bench.json");
    fs::write(
        &cfg,
        format!(
            r#"{{"iters": [1], "cameras": [{{"name": "clean", "camera": "ideal"}}], "sets": [
                {{"name": "kitti", "scene": {{"kind": "dataset", "path": "{}", "layout": "kitti"}}}},
                {{"name": "middlebury", "scene": {{"kind": "dataset", "path": "{}", "layout": "middlebury"}}}}]}}"#,
            data.join("kitti2015_000000").display(),
            data.join("middlebury_rubberwhale").display()
        ),
    )
    .unwrap();
    let out = dir.path().join("bench");
    ok(&pins(&[
        "bench-real",
        "--config",
        cfg.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--no-peers",
    ]));
    let r = read_report(&out);
    check_runs(&r, &["kitti", "middlebury"], &["clean"], &[1]);
    for (run, original) in [
        (&r["runs"][0], data.join("kitti2015_000000/flow_gt.png")),
        (
            &r["runs"][1],
            data.join("middlebury_rubberwhale/flow10.flo"),
        ),
    ] {
        let p = &run["per_pair"][0];
        let total = p["width"].as_u64().unwrap() * p["height"].as_u64().unwrap();
        let (n, mean) = mean_gt(&original);
        assert_eq!(p["pixels"].as_u64().unwrap(), n);
        assert!(n < total, "{original:?}: some flow is unknown");
        assert!((f(&p["mean_gt"]) - mean).abs() < 1e-9 * (1.0 + mean));
    }
}

#[test]
fn peers_without_python_are_skipped_with_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("bench.json");
    fs::write(
        &cfg,
        r#"{"iters": [1], "cameras": [{"name": "clean", "camera": "ideal"}], "sets": [
            {"name": "tiny", "scene": {"kind": "chairs", "width": 32, "height": 32, "sprites": [1, 1], "supersample": 1}, "count": 1}]}"#,
    )
    .unwrap();
    let out = dir.path().join("bench");
    let run = pins(&[
        "bench-real",
        "--config",
        cfg.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--python",
        "/no/such/python3",
    ]);
    ok(&run);
    let r = read_report(&out);
    assert_eq!(r["peers"]["ran"], false);
    let why = r["peers"]["skipped_because"].as_str().unwrap();
    assert!(why.contains("/no/such/python3"), "{why}");
    assert!(
        fs::read_to_string(out.join("report.md"))
            .unwrap()
            .contains("not run: ")
    );
    check_runs(&r, &["tiny"], &["clean"], &[1]);
}

#[test]
fn bad_input_is_a_clear_error_with_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let good_set =
        r#"{"name": "tiny", "scene": {"kind": "chairs", "width": 32, "height": 32}, "count": 1}"#;
    let cases: Vec<(String, Vec<&str>, &str)> = vec![
        ("{\"sets\": [".into(), vec![], "bench.json"),
        (
            format!(r#"{{"sets": [{good_set}], "iter": [1]}}"#),
            vec![],
            "iter",
        ),
        (
            r#"{"sets": [{"name": "gone", "scene": {"kind": "dataset", "path": "nowhere"}}]}"#
                .into(),
            vec![],
            "none of its 1 sets",
        ),
        (
            format!(r#"{{"sets": [{good_set}]}}"#),
            vec!["--iters", "0"],
            "--iters",
        ),
        (
            format!(r#"{{"sets": [{good_set}]}}"#),
            vec!["--weights", "no_such.safetensors"],
            "no_such.safetensors",
        ),
        (
            format!(r#"{{"sets": [{good_set}], "cameras": []}}"#),
            vec![],
            "cameras",
        ),
    ];
    for (i, (json, extra, needle)) in cases.iter().enumerate() {
        let cfg = dir.path().join("bench.json");
        fs::write(&cfg, json).unwrap();
        let out = dir.path().join(format!("out{i}"));
        let mut args = vec![
            "bench-real",
            "--config",
            cfg.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend(extra.iter().copied());
        let err = failed(&pins(&args));
        assert!(err.contains(needle), "case {i}: {err}");
        assert!(!err.contains("panicked"), "case {i}: {err}");
        assert!(!out.exists(), "case {i}: {out:?} was made");
    }
    let err = failed(&pins(&[
        "bench-real",
        "--config",
        dir.path().join("missing.json").to_str().unwrap(),
        "--out",
        dir.path().join("o").to_str().unwrap(),
    ]));
    assert!(err.contains("missing.json"), "{err}");
}
