//! The GPU backend (`--features wgpu`, Burn's cubecl backend on Vulkan) against the CPU path:
//! the shipped weights' flow on a pair, and two training steps of the real trainer (losses and
//! every updated weight), each to 1e-4. Any Vulkan driver runs it; CI uses Mesa's software
//! driver (lavapipe). Where no Vulkan device exists the tests say so and pass, unless
//! `PINS_REQUIRE_VULKAN=1` (set by CI) makes that a failure.
#![cfg(feature = "wgpu")]

mod common;
use common::{log_column, ok, pins, safetensors_f32, tiny_dataset};

use std::fs;
use std::path::{Path, PathBuf};

/// The device the tests run on (`PINS_TEST_WGPU_DEVICE`, `wgpu` by default), or `None` with a
/// message where it cannot be opened.
fn gpu() -> Option<String> {
    let name = std::env::var("PINS_TEST_WGPU_DEVICE").unwrap_or_else(|_| "wgpu".into());
    match pins::flow::device::select(&name) {
        Ok(_) => Some(name),
        Err(e) => {
            assert!(
                std::env::var("PINS_REQUIRE_VULKAN").as_deref() != Ok("1"),
                "PINS_REQUIRE_VULKAN=1 but {e}"
            );
            eprintln!("skipped: {e}");
            None
        }
    }
}

fn s(p: &Path) -> &str {
    p.to_str().expect("a UTF-8 temporary path")
}

fn flow_values(path: &Path) -> Vec<f32> {
    pins::io::read_flo(path)
        .expect("a .flo written by pins")
        .data()
        .to_vec()
}

#[test]
fn inference_matches_the_cpu() {
    let Some(gpu) = gpu() else { return };
    let d = tempfile::tempdir().unwrap();
    let data = tiny_dataset(d.path(), "data", 2, 31);
    let (img1, img2) = (data.join("00001_img1.png"), data.join("00001_img2.png"));
    let run = |device: &str| {
        let out = d.path().join(format!("{}.flo", device.replace(':', "_")));
        ok(&pins(&[
            "infer",
            "--img1",
            s(&img1),
            "--img2",
            s(&img2),
            "--out",
            s(&out),
            "--iters",
            "6",
            // The network's own flow: the refinement after it runs on the CPU either way.
            "--refine",
            "none",
            "--device",
            device,
        ]));
        flow_values(&out)
    };
    let (cpu, flow) = (run("cpu"), run(&gpu));
    assert_eq!(cpu.len(), flow.len());
    let worst = cpu
        .iter()
        .zip(&flow)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    let largest = cpu.iter().fold(0.0f32, |m, v| m.max(v.abs()));
    eprintln!(
        "{gpu} against cpu: flow differs by at most {worst:.2e} px (largest {largest:.2} px)"
    );
    assert!(
        largest > 0.1,
        "the pair should move: largest flow {largest}"
    );
    assert!(
        worst <= 1e-4 * largest.max(1.0),
        "flow differs by {worst} px"
    );
}

#[test]
fn two_training_steps_match_the_cpu() {
    let Some(gpu) = gpu() else { return };
    let d = tempfile::tempdir().unwrap();
    let data = tiny_dataset(d.path(), "data", 4, 32);
    let cfg = d.path().join("train.json");
    // Two steps from the shipped weights, so the gradients are those of a trained network, on
    // whole 80×64 frames (validation then runs at the training size, so the GPU compiles one set
    // of kernels). The learning rate is small: AdamW's first steps move every weight by about
    // the learning rate whatever its gradient, including the biases in front of an instance
    // norm, whose true gradient is zero and whose computed one is rounding noise.
    fs::write(
        &cfg,
        r#"{"model": "mms-small", "steps": 2, "batch_size": 2, "crop": [64, 80], "iters": 3,
            "lr": 1e-5, "val_fraction": 0.25, "val_every": 2, "val_max_pairs": 1,
            "val_iters": 3, "checkpoint_every": 1}"#,
    )
    .unwrap();
    let init =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("datasets/weights/mms-small.safetensors");
    let run = |device: &str| {
        let out = d.path().join(device.replace(':', "_"));
        ok(&pins(&[
            "train",
            "--config",
            s(&cfg),
            "--data",
            s(&data),
            "--out",
            s(&out),
            "--init",
            s(&init),
            "--device",
            device,
            "--quiet",
        ]));
        out
    };
    let (cpu, gpu_run) = (run("cpu"), run(&gpu));
    // log.csv: step, lr, loss, EPE, ...
    for col in [2, 3] {
        let (a, b) = (log_column(&cpu, col), log_column(&gpu_run, col));
        assert_eq!(a.len(), 2, "two logged steps");
        for (x, y) in a.iter().zip(&b) {
            assert!(
                (x - y).abs() <= 1e-4 * x.abs().max(1.0),
                "column {col}: {a:?} against {b:?}"
            );
        }
    }
    let (wa, wb) = (
        safetensors_f32(&cpu.join("last.safetensors")),
        safetensors_f32(&gpu_run.join("last.safetensors")),
    );
    assert_eq!(wa.len(), wb.len());
    let mut worst = (0.0f32, String::new());
    for ((na, a), (nb, b)) in wa.iter().zip(&wb) {
        assert_eq!(na, nb);
        for (x, y) in a.iter().zip(b) {
            if (x - y).abs() > worst.0 {
                worst = ((x - y).abs(), na.clone());
            }
        }
    }
    eprintln!(
        "{gpu} against cpu after two steps: weights differ by at most {:.2e} ({})",
        worst.0, worst.1
    );
    assert!(worst.0 <= 1e-4, "weight {} differs by {}", worst.1, worst.0);
}
