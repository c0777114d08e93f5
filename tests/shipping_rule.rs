//! `scripts/shipping_rule.py` (the training ledger's rule for shipping weights): on bench-real
//! and detect-limits reports of the shape the commands write, it ships a candidate only when it
//! is better over all pixels through the camera, no set is more than 2 % worse and every Note
//! S12 case is detected, and names what failed otherwise, down to the pairs of a set outside the
//! tolerance. Runs where Python 3 is found (`PINS_PYTHON`, else `python3`); says SKIPPED
//! otherwise.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::{Value, json};

fn python() -> Option<String> {
    common::python("shipping_rule", "json")
}

fn script() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/shipping_rule.py")
}

const SETS: [&str; 3] = ["middlebury", "kitti", "photo_warps"];

/// A bench-real report whose refined rows at 12 iterations have `epe[set][camera]` (camera 0:
/// clean, 1: through the camera) and the pooled EPE `pooled` per camera; the network-alone
/// rows are worse and must be ignored.
fn bench(epe: [[f64; 2]; 3], pooled: [f64; 2]) -> Value {
    let row =
        |method: &str, iters: u32, epe: f64| json!({"method": method, "iters": iters, "epe": epe});
    let cameras = ["clean", "camera"];
    let runs: Vec<Value> = SETS
        .iter()
        .enumerate()
        .flat_map(|(i, set)| {
            cameras.iter().enumerate().map(move |(c, cam)| {
                json!({"set": set, "camera": cam, "methods": [
                    row("mms-small", 12, 10.0 * epe[i][c]),
                    row("mms-small + variational", 4, 10.0 * epe[i][c]),
                    row("mms-small + variational", 12, epe[i][c]),
                    {"method": "zero flow", "iters": null, "epe": 99.0},
                ]})
            })
        })
        .collect();
    let summary: Vec<Value> = cameras
        .iter()
        .enumerate()
        .map(|(c, cam)| {
            json!({"camera": cam, "pooled": row("mms-small + variational", 12, pooled[c])})
        })
        .collect();
    json!({"runs": runs, "summary": summary})
}

fn s12(detected: bool) -> Value {
    json!({"start": "zero", "scores": [
        {"case": "rocket up", "iters": 12, "detected": true},
        {"case": "disc r = 3", "iters": 12, "detected": detected},
    ]})
}

/// The script's exit status and what it printed to stdout.
fn verdict(out: &Output) -> (Option<i32>, String) {
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
    )
}

fn run(py: &str, dir: &Path, cand: &Value, ship: &Value, s12s: &[Value]) -> Output {
    let write = |name: &str, v: &Value| {
        let p = dir.join(name);
        std::fs::write(&p, v.to_string()).unwrap();
        p
    };
    let (c, s) = (write("cand.json", cand), write("ship.json", ship));
    let mut cmd = Command::new(py);
    cmd.arg(script()).arg(&c).arg(&s);
    if !s12s.is_empty() {
        cmd.arg("--s12");
        for (i, v) in s12s.iter().enumerate() {
            cmd.arg(write(&format!("s12_{i}.json"), v));
        }
    }
    cmd.output().unwrap()
}

const SHIPPED: [[f64; 2]; 3] = [[0.112, 0.652], [12.2, 14.3], [2.41, 3.53]];

#[test]
fn ships_only_better_weights_with_no_set_worse_and_every_case_found() {
    let Some(py) = python() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let ship = bench(SHIPPED, [2.23, 3.28]);

    // Better over all pixels, Middlebury through the camera 1.5 % worse: within the rule.
    let mut e = SHIPPED;
    e[0][1] *= 1.015;
    e[2][1] *= 0.9;
    let (code, text) = verdict(&run(
        &py,
        tmp.path(),
        &bench(e, [2.20, 3.10]),
        &ship,
        &[s12(true)],
    ));
    assert_eq!(code, Some(0), "{text}");
    assert!(text.contains("verdict: ships"), "{text}");
    assert!(
        text.contains("| middlebury | camera | 0.652 | 0.662 | +1.5% | yes |"),
        "{text}"
    );

    // The same with KITTI clean 3 % worse: the set is named.
    e[1][0] *= 1.03;
    let (code, text) = verdict(&run(
        &py,
        tmp.path(),
        &bench(e, [2.20, 3.10]),
        &ship,
        &[s12(true)],
    ));
    assert_eq!(code, Some(1), "{text}");
    assert!(text.contains("kitti clean +3.0%"), "{text}");

    // Where the reports have the EPE by speed, its change is shown beside the rule, not in it.
    let with_speed = |mut r: Value, s40: f64| {
        r["summary"][1]["pooled"]["by_speed"] =
            json!({"pixels": [900, 80, 20], "epe": [0.5, 4.0, s40]});
        r
    };
    let (code, text) = verdict(&run(
        &py,
        tmp.path(),
        &with_speed(bench(e, [2.20, 3.10]), 30.0),
        &with_speed(ship.clone(), 20.0),
        &[s12(true)],
    ));
    assert_eq!(code, Some(1), "{text}");
    assert!(
        text.contains("| all pixels moving s40+ (20) | camera | 20.000 | 30.000 | +50.0% | |"),
        "{text}"
    );
    assert!(!text.contains("s40+ (20) | clean"), "{text}");

    // Every set better, but not over all pixels through the camera (the pooled score).
    let better = SHIPPED.map(|s| s.map(|x| 0.99 * x));
    let (code, text) = verdict(&run(
        &py,
        tmp.path(),
        &bench(better, [2.20, 3.30]),
        &ship,
        &[],
    ));
    assert_eq!(code, Some(1), "{text}");
    assert!(text.contains("not better over all pixels through the camera (3.300 against 3.280)"));

    // Better everywhere, but a Note S12 case lost.
    let (code, text) = verdict(&run(
        &py,
        tmp.path(),
        &bench(better, [2.20, 3.10]),
        &ship,
        &[s12(true), s12(false)],
    ));
    assert_eq!(code, Some(1), "{text}");
    assert!(text.contains("disc r = 3 @12 (zero start)"), "{text}");
}

#[test]
fn unusable_reports_are_refused_with_the_reason() {
    let Some(py) = python() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let ship = bench(SHIPPED, [2.23, 3.28]);
    // A detect-limits report where a bench-real one belongs.
    let out = run(&py, tmp.path(), &s12(true), &ship, &[]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("no runs"));
    // Reports over different sets.
    let mut fewer = bench(SHIPPED, [2.23, 3.28]);
    fewer["runs"].as_array_mut().unwrap().pop();
    let out = run(&py, tmp.path(), &fewer, &ship, &[]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("different sets"));
    // Not JSON at all.
    std::fs::write(tmp.path().join("bad.json"), "{ no").unwrap();
    let out = Command::new(&py)
        .arg(script())
        .arg(tmp.path().join("bad.json"))
        .arg(tmp.path().join("bad.json"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("bad.json"));
}

/// `report` with two pairs in KITTI through the camera (set index 1, camera 1), their refined
/// 12-iteration EPEs `epe` and EPEs over pixels moving 40 px or more `fast`.
fn with_pairs(mut report: Value, epe: [f64; 2], fast: [f64; 2]) -> Value {
    let per_pair: Vec<Value> = (0..2)
        .map(|i| {
            json!({"name": format!("0000{i}"), "source": format!("src{i}"), "mean_gt": 30.0 + i as f64,
                "methods": [
                    {"method": "mms-small", "iters": 12, "epe": 99.0},
                    {"method": "mms-small + variational", "iters": 12, "epe": epe[i],
                     "by_speed": {"pixels": [10, 10, 5], "epe": [1.0, 2.0, fast[i]]}},
                ]})
        })
        .collect();
    report["runs"][3]["per_pair"] = Value::Array(per_pair);
    report
}

#[test]
fn the_pairs_of_a_set_outside_the_tolerance_are_shown() {
    let Some(py) = python() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let ship = with_pairs(bench(SHIPPED, [2.23, 3.28]), [14.0, 14.6], [20.0, 21.0]);
    // KITTI through the camera 10 % worse, all of it in its second pair's fast pixels.
    let mut e = SHIPPED;
    e[1][1] *= 1.1;
    let cand = with_pairs(bench(e, [2.20, 3.10]), [14.0, 17.5], [20.0, 38.5]);
    let (code, text) = verdict(&run(&py, tmp.path(), &cand, &ship, &[]));
    assert_eq!(code, Some(1), "{text}");
    assert!(
        text.contains(
            "| kitti | camera | 00001 (src1) | 31.0 | 14.600 | 17.500 | +19.9% | 21.00 | 38.50 |"
        ),
        "{text}"
    );
    assert!(
        text.contains("| kitti | camera | 00000 (src0) | 30.0 | 14.000 | 14.000 | +0.0% |"),
        "{text}"
    );
    // Within the tolerance everywhere: no pair table.
    let cand = with_pairs(bench(SHIPPED, [2.20, 3.10]), [14.0, 14.6], [20.0, 21.0]);
    let (code, text) = verdict(&run(&py, tmp.path(), &cand, &ship, &[]));
    assert_eq!(code, Some(0), "{text}");
    assert!(!text.contains("pair (source)"), "{text}");
}
