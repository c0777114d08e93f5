//! Data-parallel training (`pins train --devices`): two CPU devices with half the batch each
//! take the same steps as one device with the whole batch (loss and updated weights to 1e-6),
//! a resumed two-device run continues bit-exactly, and a batch smaller than the device count is
//! refused.

mod common;
use common::{failed, log_column, ok, pins, safetensors_f32, tiny_dataset};

use std::fs;
use std::path::{Path, PathBuf};

fn config(dir: &Path, batch: usize, steps: usize) -> PathBuf {
    let p = dir.join(format!("train{batch}_{steps}.json"));
    fs::write(
        &p,
        format!(
            r#"{{"model": "mms-small", "steps": {steps}, "batch_size": {batch}, "crop": [64, 64],
                "iters": 2, "val_fraction": 0.2, "val_every": 4, "val_max_pairs": 1,
                "val_iters": 2, "checkpoint_every": 1}}"#
        ),
    )
    .unwrap();
    p
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn two_devices_with_half_the_batch_equal_one_with_all_of_it() {
    let d = tempfile::tempdir().unwrap();
    let data = tiny_dataset(d.path(), "data", 6, 5);
    let run = |name: &str, steps: usize, extra: &[&str]| {
        let cfg = config(d.path(), 2, steps);
        let out = d.path().join(name);
        let mut args = vec![
            "train",
            "--config",
            s(&cfg),
            "--data",
            s(&data),
            "--out",
            s(&out),
            "--quiet",
        ];
        args.extend_from_slice(extra);
        ok(&pins(&args));
        out
    };
    // One step: the loss, the EPE and every updated weight agree to 1e-6.
    let (one, two) = (run("one", 1, &[]), run("two", 1, &["--devices", "cpu,cpu"]));
    let close = |a: &[f64], b: &[f64], tol: f64| {
        a.len() == b.len()
            && a.iter()
                .zip(b)
                .all(|(x, y)| (x - y).abs() <= tol * x.abs().max(1.0))
    };
    for col in [2, 3] {
        let (a, b) = (log_column(&one, col), log_column(&two, col));
        assert!(close(&a, &b, 1e-6), "column {col}: {a:?} against {b:?}");
    }
    let (wa, wb) = (
        safetensors_f32(&one.join("last.safetensors")),
        safetensors_f32(&two.join("last.safetensors")),
    );
    assert_eq!(wa.len(), wb.len());
    assert!(!wa.is_empty());
    let mut worst = 0.0f32;
    for ((na, a), (nb, b)) in wa.iter().zip(&wb) {
        assert_eq!(na, nb);
        for (x, y) in a.iter().zip(b) {
            worst = worst.max((x - y).abs());
        }
    }
    assert!(worst <= 1e-6, "weights differ by {worst}");
    // Four steps: the losses still agree. (Not every weight: the biases in front of an
    // instance norm have a true gradient of zero, so theirs is rounding noise, which AdamW
    // normalises into steps of the learning rate's size whatever the summation order.)
    let (one, two) = (
        run("one4", 4, &[]),
        run("two4", 4, &["--devices", "cpu,cpu"]),
    );
    for col in [2, 3] {
        let (a, b) = (log_column(&one, col), log_column(&two, col));
        assert!(close(&a, &b, 1e-4), "column {col}: {a:?} against {b:?}");
    }
    let cfg = config(d.path(), 2, 4);
    // Interrupted after 2 steps and resumed on two devices: bit-exact with the straight run.
    let part = d.path().join("part");
    let args = [
        "train",
        "--config",
        s(&cfg),
        "--data",
        s(&data),
        "--out",
        s(&part),
        "--quiet",
        "--devices",
        "cpu,cpu",
    ];
    let mut first = args.to_vec();
    first.extend(["--stop-after", "2"]);
    ok(&pins(&first));
    let mut again = args.to_vec();
    again.push("--resume");
    ok(&pins(&again));
    assert!(
        fs::read(part.join("last.safetensors")).unwrap()
            == fs::read(two.join("last.safetensors")).unwrap(),
        "a resumed two-device run differs"
    );
    // Two devices need at least two examples per batch.
    let small = config(d.path(), 1, 4);
    let err = failed(&pins(&[
        "train",
        "--config",
        s(&small),
        "--data",
        s(&data),
        "--out",
        s(&d.path().join("x")),
        "--devices",
        "cpu,cpu",
    ]));
    assert!(
        err.contains("--devices") && err.contains("batch_size"),
        "{err}"
    );
    let err = failed(&pins(&[
        "train",
        "--data",
        s(&data),
        "--out",
        s(&d.path().join("y")),
        "--devices",
        "cpu,tpu",
    ]));
    assert!(err.contains("tpu"), "{err}");
}
