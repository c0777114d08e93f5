//! A cool-down branch may anneal on data other than its run's (warmup–stable–decay's decay-phase
//! mix, Note S11's training in chunks): it says so, its checkpoint and weights record the data it
//! cooled down on, and its resumes hold to those; a plain resume, a branch that does not cool
//! down and a cool-down of a cool-down are refused on other data, leaving nothing behind.

mod common;
use common::{failed, ok, train};

use std::fs;
use std::path::Path;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn state(run: &Path) -> serde_json::Value {
    serde_json::from_str(&fs::read_to_string(run.join("checkpoint/state.json")).unwrap()).unwrap()
}

#[test]
fn a_cool_down_anneals_on_other_data_and_a_resume_does_not() {
    let tmp = tempfile::tempdir().unwrap();
    let data = common::tiny_dataset(tmp.path(), "data", 4, 3);
    let other = common::tiny_dataset(tmp.path(), "other", 5, 9);
    let cfg = tmp.path().join("train.json");
    fs::write(
        &cfg,
        r#"{"model": "mms-small", "steps": 20, "batch_size": 1, "crop": [64, 64], "iters": 2,
            "val_fraction": 0.25, "val_every": 2, "val_max_pairs": 1, "val_iters": 2,
            "checkpoint_every": 1000, "restart_warmup": 2}"#,
    )
    .unwrap();
    let trunk = tmp.path().join("trunk");
    ok(&train(&cfg, &data, &trunk, &["--stop-after", "3"], None));
    let trunk_state = fs::read(trunk.join("checkpoint/state.json")).unwrap();

    // Refused on other data: the run's own resume, a branch that does not cool down.
    let err = failed(&train(&cfg, &other, &trunk, &["--resume"], None));
    assert!(
        err.contains("--data") && err.contains("5 pairs") && err.contains("--cooldown"),
        "{err}"
    );
    let fork = tmp.path().join("fork");
    let err = failed(&train(
        &cfg,
        &other,
        &fork,
        &["--branch-from", s(&trunk)],
        None,
    ));
    assert!(err.contains("--data"), "{err}");
    assert!(!fork.exists(), "a refused branch leaves no folder");
    assert_eq!(
        fs::read(trunk.join("checkpoint/state.json")).unwrap(),
        trunk_state
    );

    // A cool-down on the other data: it says which data it left, and records its own.
    let branch = tmp.path().join("branch");
    let cool = [
        "--branch-from",
        s(&trunk),
        "--cooldown",
        "4",
        "--stop-after",
        "2",
    ];
    let out = ok(&train(&cfg, &other, &branch, &cool, None));
    assert!(
        out.contains("anneals on") && out.contains("5 pairs") && out.contains("4 pairs"),
        "{out}"
    );
    let st = state(&branch);
    assert_eq!(st["step"], 5);
    assert_eq!(st["data"], s(&other));
    let weights = branch.join("last.safetensors");
    let stamp =
        pins::flow::train::stamp::TrainingStamp::read(&fs::read(&weights).unwrap(), &weights)
            .unwrap()
            .expect("a training stamp");
    assert_eq!(stamp.data.pairs, 5);
    // Its resumes hold to the data it cools down on, and it ends where it was set to end.
    let err = failed(&train(&cfg, &data, &branch, &["--resume"], None));
    assert!(err.contains("--data") && err.contains("4 pairs"), "{err}");
    let out = ok(&train(&cfg, &other, &branch, &["--resume"], None));
    assert!(
        !out.contains("anneals on"),
        "a resume changes no data: {out}"
    );
    assert_eq!(state(&branch)["step"], 7);
    // The run is untouched; a cool-down of the cool-down is still refused other data.
    assert_eq!(
        fs::read(trunk.join("checkpoint/state.json")).unwrap(),
        trunk_state
    );
    let again = tmp.path().join("again");
    let err = failed(&train(
        &cfg,
        &data,
        &again,
        &["--branch-from", s(&branch), "--cooldown", "4"],
        None,
    ));
    assert!(err.contains("--data") && err.contains("5 pairs"), "{err}");
    assert!(!again.exists(), "a refused branch leaves no folder");
}
