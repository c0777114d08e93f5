//! `pins train --data mix.json`: pairs made on the fly from weighted generator configs — a run
//! stopped and resumed repeats the uninterrupted one byte for byte, another stream is refused
//! on resume, and a crop larger than a source's frames is refused before any folder is made.

mod common;
use common::{failed, ok, pins};

use std::fs;
use std::path::{Path, PathBuf};

/// Two small chairs sources through the default camera, weighted 1 : 2.
fn stream(dir: &Path, weight_b: u32) -> PathBuf {
    fs::write(
        dir.join("a.json"),
        r#"{"count": 1, "seed": 21, "scene": {"kind": "chairs", "width": 80, "height": 64,
            "supersample": 1, "sprites": [1, 2]}}"#,
    )
    .unwrap();
    fs::write(
        dir.join("b.json"),
        r#"{"count": 1, "seed": 22, "scene": {"kind": "chairs", "width": 96, "height": 80,
            "supersample": 1, "sprites": [1, 3], "translation_law": "log_uniform",
            "min_translation": 0.1, "max_translation": 4.0}}"#,
    )
    .unwrap();
    let p = dir.join("mix.json");
    fs::write(
        &p,
        format!(
            r#"{{"sources": [{{"generator": "a.json", "weight": 1}},
                            {{"generator": "b.json", "weight": {weight_b}}}]}}"#
        ),
    )
    .unwrap();
    p
}

fn config(dir: &Path, crop: usize) -> PathBuf {
    let p = dir.join(format!("train{crop}.json"));
    fs::write(
        &p,
        format!(
            r#"{{"model": "mms-small", "steps": 4, "batch_size": 2, "crop": [{crop}, {crop}],
                "iters": 2, "val_every": 2, "val_max_pairs": 2, "val_iters": 2,
                "checkpoint_every": 1}}"#
        ),
    )
    .unwrap();
    p
}

#[test]
fn a_stream_run_resumes_exactly_and_refuses_another_stream() {
    let tmp = tempfile::tempdir().unwrap();
    let mix = stream(tmp.path(), 2);
    let cfg = config(tmp.path(), 64);
    let (c, d) = (cfg.to_str().unwrap(), mix.to_str().unwrap());
    let straight = tmp.path().join("straight");
    let out = ok(&pins(&[
        "train",
        "--config",
        c,
        "--data",
        d,
        "--out",
        straight.to_str().unwrap(),
        "--quiet",
    ]));
    assert!(!out.contains("NaN"), "{out}");
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
    ok(&pins(&[
        "train", "--config", c, "--data", d, "--out", co, "--resume", "--quiet",
    ]));
    let rows = common::log_steps(&straight);
    assert_eq!(rows.len(), 4);
    assert_eq!(
        rows,
        common::log_steps(&chunked),
        "a resumed run repeats its steps"
    );
    // Validation ran on the stream's own pairs (steps 2 and 4 have a score).
    let log = fs::read_to_string(straight.join("log.csv")).unwrap();
    let scored = log.lines().skip(1).filter(|l| !l.ends_with(",,")).count();
    assert_eq!(scored, 2, "{log}");
    for name in [
        "last.safetensors",
        "best.safetensors",
        "checkpoint/optim-0000004.bin",
    ] {
        assert!(
            fs::read(straight.join(name)).unwrap() == fs::read(chunked.join(name)).unwrap(),
            "{name} differs between an interrupted and an uninterrupted run"
        );
    }
    // The run's config records the stream file as its data.
    let run_config = fs::read_to_string(straight.join("config.json")).unwrap();
    assert!(run_config.contains("mix.json"), "{run_config}");

    // Another weight is another stream: resuming on it is refused, the run untouched.
    let before = fs::read(chunked.join("checkpoint/state.json")).unwrap();
    let other = tmp.path().join("other");
    fs::create_dir_all(&other).unwrap();
    let mix2 = stream(&other, 3);
    let err = failed(&pins(&[
        "train",
        "--config",
        c,
        "--data",
        mix2.to_str().unwrap(),
        "--out",
        co,
        "--resume",
        "--quiet",
    ]));
    assert!(err.contains("made on the fly"), "{err}");
    assert_eq!(
        fs::read(chunked.join("checkpoint/state.json")).unwrap(),
        before
    );

    // A crop larger than the smaller source's 80x64 frames: refused, no run folder made.
    let big = config(tmp.path(), 72);
    let none = tmp.path().join("none");
    let err = failed(&pins(&[
        "train",
        "--config",
        big.to_str().unwrap(),
        "--data",
        d,
        "--out",
        none.to_str().unwrap(),
        "--quiet",
    ]));
    assert!(err.contains("crop") && err.contains("64x80"), "{err}");
    assert!(!none.exists());
}
