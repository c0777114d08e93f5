//! Training as a campaign (Note S11): identical runs are byte-identical at any thread count; a
//! session ends at its time budget or on SIGTERM with a checkpoint from which `--resume`
//! continues exactly; `--continue-from` goes on from a weights file's training stamp when the
//! checkpoint is gone; a cool-down branches off a run's checkpoint and ends at a rate of zero;
//! bad input is named.

mod common;
use common::{failed, log_column, ok, pins, train};

use std::fs;
use std::path::{Path, PathBuf};

fn config(dir: &Path, steps: usize, batch: usize) -> PathBuf {
    let p = dir.join(format!("train_{steps}_{batch}.json"));
    fs::write(
        &p,
        format!(
            r#"{{"model": "mms-small", "steps": {steps}, "batch_size": {batch}, "crop": [64, 64],
                "iters": 2, "val_fraction": 0.25, "val_every": 2, "val_max_pairs": 1,
                "val_iters": 2, "checkpoint_every": 1000, "restart_warmup": 2}}"#
        ),
    )
    .unwrap();
    p
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn state_step(run: &Path) -> u64 {
    let text = fs::read_to_string(run.join("checkpoint/state.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["step"].as_u64().unwrap()
}

#[test]
fn identical_runs_are_byte_identical_at_one_and_two_threads() {
    let tmp = tempfile::tempdir().unwrap();
    let data = common::tiny_dataset(tmp.path(), "data", 6, 5);
    let cfg = config(tmp.path(), 3, 2);
    let mut files = Vec::new();
    for (i, threads) in [1, 2, 2].into_iter().enumerate() {
        let run = tmp.path().join(format!("run{i}"));
        ok(&train(&cfg, &data, &run, &[], Some(threads)));
        files.push((threads, fs::read(run.join("last.safetensors")).unwrap()));
    }
    for (threads, bytes) in &files[1..] {
        assert!(
            *bytes == files[0].1,
            "the weights after 3 steps on {threads} threads differ from those on 1 thread"
        );
    }
}

#[test]
fn a_time_budget_ends_the_session_with_a_checkpoint_and_resume_continues_exactly() {
    let tmp = tempfile::tempdir().unwrap();
    let data = common::tiny_dataset(tmp.path(), "data", 4, 3);
    let cfg = config(tmp.path(), 100_000, 1);
    let straight = tmp.path().join("straight");
    let run_with = |run: &Path, extra: &[&str]| train(&cfg, &data, run, extra, None);
    // A budget of one second ends the session before the step that would pass it, however
    // fast this machine is (the run has 100 000 steps): a checkpoint at the last step taken.
    let budgeted = tmp.path().join("budgeted");
    let out = ok(&run_with(&budgeted, &["--time-budget", "1s"]));
    assert!(out.contains("stopped by its time budget"), "{out}");
    let taken = rows_or_empty(&budgeted).len();
    assert_eq!(state_step(&budgeted), taken as u64);
    // Resumed for two more steps, it equals a run that took them all at once.
    ok(&run_with(&budgeted, &["--resume", "--stop-after", "2"]));
    let all = (taken + 2).to_string();
    ok(&run_with(&straight, &["--stop-after", &all]));
    assert_eq!(common::log_steps(&straight), common::log_steps(&budgeted));
    assert!(
        fs::read(straight.join("last.safetensors")).unwrap()
            == fs::read(budgeted.join("last.safetensors")).unwrap(),
        "a run stopped by its budget and resumed must end with the same weights"
    );
    let err = failed(&run_with(&tmp.path().join("bad"), &["--time-budget", "5x"]));
    assert!(err.contains("--time-budget") && err.contains("5x"), "{err}");
    assert!(
        !tmp.path().join("bad").exists(),
        "a refused run leaves no folder"
    );
}

#[cfg(unix)]
#[test]
fn sigterm_ends_the_session_at_the_next_step_with_a_checkpoint() {
    use std::process::{Command, Stdio};
    use std::time::{Duration, Instant};
    let tmp = tempfile::tempdir().unwrap();
    let data = common::tiny_dataset(tmp.path(), "data", 4, 3);
    let cfg = config(tmp.path(), 100_000, 1);
    let run = tmp.path().join("run");
    let child = Command::new(env!("CARGO_BIN_EXE_pins"))
        .args([
            "train",
            "--config",
            s(&cfg),
            "--data",
            s(&data),
            "--out",
            s(&run),
            "--quiet",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Wait for a logged step (the handler is installed before the first one).
    let t0 = Instant::now();
    while rows_or_empty(&run).is_empty() {
        assert!(t0.elapsed() < Duration::from_secs(600), "no step logged");
        std::thread::sleep(Duration::from_millis(50));
    }
    let status = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let out = child.wait_with_output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "exit {:?}: {}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("stopped by a stop request"), "{stdout}");
    let taken = common::log_steps(&run).len() as u64;
    assert!(taken < 100_000);
    assert_eq!(
        state_step(&run),
        taken,
        "the checkpoint is the last step taken"
    );
}

/// The step of a weights file's training stamp.
fn stamp_step(weights: &Path) -> usize {
    let bytes = fs::read(weights).unwrap();
    let n = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
    let header: serde_json::Value = serde_json::from_slice(&bytes[8..8 + n]).unwrap();
    let stamp = header["__metadata__"]["pins.training"].as_str().unwrap();
    let stamp: serde_json::Value = serde_json::from_str(stamp).unwrap();
    stamp["step"].as_u64().unwrap() as usize
}

fn rows_or_empty(run: &Path) -> Vec<String> {
    if run.join("log.csv").is_file() {
        common::log_steps(run)
    } else {
        Vec::new()
    }
}

#[test]
fn continue_from_goes_on_from_the_weights_stamp_with_a_warm_up() {
    let tmp = tempfile::tempdir().unwrap();
    let data = common::tiny_dataset(tmp.path(), "data", 4, 3);
    let cfg = config(tmp.path(), 6, 1);
    let first = tmp.path().join("first");
    ok(&train(&cfg, &data, &first, &["--stop-after", "3"], None));
    // The exported weights keep the stamp: the checkpoint is gone, the export is all there is.
    let exported = tmp.path().join("w.safetensors");
    ok(&pins(&[
        "export",
        "--run",
        s(&first),
        "--out",
        s(&exported),
    ]));
    fs::remove_dir_all(&first).unwrap();
    let second = tmp.path().join("second");
    let out = ok(&train(
        &cfg,
        &data,
        &second,
        &["--continue-from", s(&exported)],
        None,
    ));
    assert!(out.contains("6 steps (6 pairs seen)"), "{out}");
    // The export is the run's best weights (validated at step 2): the run goes on from there.
    let at = stamp_step(&exported);
    assert_eq!(at, 2);
    let steps: Vec<usize> = log_column(&second, 0).iter().map(|&v| v as usize).collect();
    assert_eq!(
        steps,
        (at + 1..=6).collect::<Vec<_>>(),
        "the run goes on after step {at}"
    );
    // The schedule's rate at step 4, from an uninterrupted run, against the warm-up's.
    let straight = tmp.path().join("straight");
    ok(&train(&cfg, &data, &straight, &[], None));
    let lr = |run: &Path, step: usize| log_column(run, 1)[step - 1];
    let lr_after = |step: usize| log_column(&second, 1)[step - at - 1];
    // A warm-up of 2 steps from a 25th of the schedule's rate; the log writes 7 digits.
    assert!((lr_after(3) / (lr(&straight, 3) / 25.0) - 1.0).abs() < 1e-5);
    assert!(lr_after(4) > lr_after(3) && lr_after(4) < lr(&straight, 4));
    for step in 5..=6 {
        assert_eq!(lr_after(step), lr(&straight, step), "the warm-up is over");
    }

    // A changed config, weights without a stamp, and --continue-from with --resume are named.
    let other = tmp.path().join("other.json");
    fs::write(
        &other,
        fs::read_to_string(&cfg)
            .unwrap()
            .replace(r#""iters": 2"#, r#""iters": 3"#),
    )
    .unwrap();
    let err = failed(&train(
        &other,
        &data,
        &tmp.path().join("x"),
        &["--continue-from", s(&exported)],
        None,
    ));
    assert!(
        err.contains("another config") && err.contains("--init"),
        "{err}"
    );
    let shipped =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("datasets/weights/mms-small.safetensors");
    let err = failed(&train(
        &cfg,
        &data,
        &tmp.path().join("y"),
        &["--continue-from", s(&shipped)],
        None,
    ));
    assert!(err.contains("no training stamp"), "{err}");
    assert!(!tmp.path().join("x").exists() && !tmp.path().join("y").exists());
}

#[test]
fn a_cool_down_branches_off_the_run_and_takes_the_rate_to_zero() {
    let tmp = tempfile::tempdir().unwrap();
    let data = common::tiny_dataset(tmp.path(), "data", 4, 3);
    let cfg = config(tmp.path(), 20, 1);
    let trunk = tmp.path().join("trunk");
    ok(&train(&cfg, &data, &trunk, &["--stop-after", "3"], None));
    let trunk_weights = fs::read(trunk.join("last.safetensors")).unwrap();
    let branch = tmp.path().join("branch");
    let out = ok(&train(
        &cfg,
        &data,
        &branch,
        &["--branch-from", s(&trunk), "--cooldown", "4"],
        None,
    ));
    assert!(out.contains("7 steps (7 pairs seen)"), "{out}");
    // Its best weights are its own: the first validation after the branch writes them.
    let best = stamp_step(&branch.join("best.safetensors"));
    assert!((4..=7).contains(&best), "best.safetensors from step {best}");
    // Stopped halfway and resumed, a cool-down ends where it ends in one go: the checkpoint
    // keeps it, and --resume needs no --cooldown.
    let halves = tmp.path().join("halves");
    let first_half = [
        "--branch-from",
        s(&trunk),
        "--cooldown",
        "4",
        "--stop-after",
        "1",
    ];
    ok(&train(&cfg, &data, &halves, &first_half, None));
    ok(&train(&cfg, &data, &halves, &["--resume"], None));
    assert_eq!(common::log_steps(&halves), common::log_steps(&branch));
    assert!(
        fs::read(halves.join("last.safetensors")).unwrap()
            == fs::read(branch.join("last.safetensors")).unwrap(),
        "a cool-down stopped and resumed must end with the same weights"
    );
    let out = ok(&train(&cfg, &data, &halves, &["--resume"], None));
    assert!(out.contains("already complete"), "{out}");

    // The run itself is untouched: it stands at step 3 and goes on on its own schedule.
    assert_eq!(state_step(&trunk), 3);
    assert!(fs::read(trunk.join("last.safetensors")).unwrap() == trunk_weights);
    ok(&train(
        &cfg,
        &data,
        &trunk,
        &["--resume", "--stop-after", "4"],
        None,
    ));
    // The branch's log begins with the run's rows; then its rate is the run's times 1 − √t.
    let (run_lr, branch_lr) = (log_column(&trunk, 1), log_column(&branch, 1));
    assert_eq!(branch_lr.len(), 7);
    assert_eq!(branch_lr[..3], run_lr[..3]);
    for (k, step) in (4..=7).enumerate() {
        let want = run_lr[step - 1] * (1.0 - (k as f64 / 4.0).sqrt());
        let got = branch_lr[step - 1];
        assert!(
            (got / want - 1.0).abs() < 1e-5,
            "step {step}: {got} against {want}"
        );
    }
    // The branch's first step is the run's own step 4 (the same rate); they part after it.
    let (run_loss, branch_loss) = (log_column(&trunk, 2), log_column(&branch, 2));
    assert_eq!(branch_loss[3], run_loss[3]);
    assert_ne!(branch_loss[6], run_loss[6]);

    // Its weights stand off the run's schedule: a warm restart from them is refused.
    let err = failed(&train(
        &cfg,
        &data,
        &tmp.path().join("x"),
        &["--continue-from", s(&branch.join("last.safetensors"))],
        None,
    ));
    assert!(
        err.contains("cool-down (steps 3–7)") && err.contains("--init"),
        "{err}"
    );
    // A cool-down longer than what is left, another length on resume, a new run, a missing
    // run and an occupied folder are named, and leave no folder.
    let none = tmp.path().join("none");
    let cases: [(&[&str], &str); 5] = [
        (
            &["--branch-from", s(&trunk), "--cooldown", "30"],
            "at most 13 are left",
        ),
        (
            &["--resume", "--cooldown", "2"],
            "cooling down over 4 steps",
        ),
        (&["--cooldown", "2"], "needs a run to cool down"),
        (
            &["--branch-from", s(&none), "--cooldown", "2"],
            "no checkpoint to branch from",
        ),
        (&["--branch-from", s(&trunk)], "already holds a run"),
    ];
    for (i, (extra, want)) in cases.iter().enumerate() {
        let out_dir = match i {
            1 | 4 => branch.clone(),
            _ => tmp.path().join(format!("refused{i}")),
        };
        let err = failed(&train(&cfg, &data, &out_dir, extra, None));
        assert!(err.contains(want), "{extra:?}: {err}");
        assert!(
            !tmp.path().join(format!("refused{i}")).exists(),
            "{extra:?}"
        );
    }
}

/// Runs `scripts/train_campaign.sh ARGS` with the test's binary and `env`; (success, stdout +
/// stderr).
/// `scripts/train_campaign.sh ARGS` with this build's pins and the environment `env`, `extra`.
fn campaign_command(
    args: &[&str],
    env: &[(&str, &Path)],
    extra: &[(&str, &str)],
) -> std::process::Command {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut cmd = std::process::Command::new("bash");
    cmd.arg(root.join("scripts/train_campaign.sh"))
        .args(args)
        .env("PINS", env!("CARGO_BIN_EXE_pins"));
    for (k, v) in env {
        cmd.env(k, v);
    }
    for (k, v) in extra {
        cmd.env(k, v);
    }
    cmd
}

fn campaign(args: &[&str], env: &[(&str, &Path)], extra: &[(&str, &str)]) -> (bool, String) {
    let out = campaign_command(args, env, extra).output().unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    (out.status.success(), text)
}

#[test]
fn the_campaign_script_continues_from_wherever_it_stands() {
    let tmp = tempfile::tempdir().unwrap();
    let (c, work, out) = (
        tmp.path().join("campaign"),
        tmp.path().join("work"),
        tmp.path().join("gpu_out"),
    );
    let env = [("CAMPAIGN", c.as_path()), ("WORK", work.as_path())];
    let (ok_, text) = campaign(&["status"], &env, &[]);
    assert!(!ok_ && text.contains("no campaign folder"), "{text}");
    fs::create_dir_all(c.join("data")).unwrap();
    fs::write(
        c.join("train.json"),
        r#"{"model": "mms-small", "steps": 100, "batch_size": 1, "crop": [64, 64], "iters": 2,
            "val_fraction": 0.25, "val_every": 4, "val_max_pairs": 1, "val_iters": 2,
            "checkpoint_every": 1000, "restart_warmup": 2}"#,
    )
    .unwrap();
    for (name, seed) in [("a", 1), ("b", 2)] {
        fs::write(
            c.join(format!("data/{name}.json")),
            format!(
                r#"{{"count": 1, "seed": {seed}, "scene": {{"kind": "chairs", "width": 80, "height": 64, "supersample": 1}}}}"#
            ),
        )
        .unwrap();
    }
    let (ok_, text) = campaign(&["status"], &env, &[]);
    assert!(!ok_ && text.contains("no stream.json"), "{text}");
    fs::write(
        c.join("stream.json"),
        r#"{"sources": [{"generator": "data/a.json", "weight": 3},
                        {"generator": "data/b.json", "weight": 2}]}"#,
    )
    .unwrap();
    // A first session of one second: from the shipped weights, ended by its budget.
    let (ok_, text) = campaign(&["run", "1s"], &env, &[]);
    assert!(ok_, "{text}");
    assert!(
        text.contains("pairs made on the fly") && text.contains("starting: --init"),
        "{text}"
    );
    assert!(text.contains("stopped by its time budget"), "{text}");
    // A cool-down branches off where the run stands; a rerun resumes the branch. (On a run
    // stopped after 3 steps in a folder of its own, whatever this machine's speed.)
    let work2 = tmp.path().join("work2");
    ok(&pins(&[
        "train",
        "--config",
        s(&c.join("train.json")),
        "--data",
        s(&c.join("stream.json")),
        "--out",
        s(&work2.join("run")),
        "--stop-after",
        "3",
        "--quiet",
    ]));
    let env2 = [("CAMPAIGN", c.as_path()), ("WORK", work2.as_path())];
    let (ok_, text) = campaign(&["cooldown", "2"], &env2, &[]);
    assert!(
        ok_ && text.contains("cooling down: --branch-from"),
        "{text}"
    );
    assert_eq!(state_step(&work2.join("cooldown-3")), 5, "{text}");
    let (ok_, text) = campaign(&["cooldown", "2"], &env2, &[]);
    assert!(
        ok_ && text.contains("--resume") && text.contains("already complete"),
        "{text}"
    );
    let (ok_, text) = campaign(&["cooldown", "x"], &env2, &[]);
    assert!(
        !ok_ && text.contains("STEPS must be a positive integer"),
        "{text}"
    );
    // A campaign with a cooldown.json anneals on that mix; the run keeps its stream.
    let mix = c.join("cooldown.json");
    fs::write(
        &mix,
        r#"{"sources": [{"generator": "data/a.json", "weight": 1},
                        {"generator": "data/b.json", "weight": 4}]}"#,
    )
    .unwrap();
    fs::remove_dir_all(work2.join("cooldown-3")).unwrap();
    let (ok_, text) = campaign(&["cooldown", "2"], &env2, &[]);
    assert!(ok_ && text.contains("anneals on"), "{text}");
    let branch: serde_json::Value = serde_json::from_str(
        &fs::read_to_string(work2.join("cooldown-3/checkpoint/state.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(branch["data"], s(&mix), "{text}");
    assert_eq!(branch["step"], 5, "{text}");
    fs::remove_file(&mix).unwrap();
    // Its weights committed, its checkpoint lost: a warm restart from the weights.
    let weights = c.join("weights.safetensors");
    fs::copy(work.join("run/last.safetensors"), &weights).unwrap();
    fs::remove_dir_all(work.join("run")).unwrap();
    let (ok_, text) = campaign(&["run", "1h"], &env, &[]);
    assert!(ok_, "{text}");
    assert!(
        text.contains("starting: --continue-from") && text.contains("step 100 of 100"),
        "{text}"
    );
    // Every checkpoint kept a snapshot; their mean is a weights file of the network.
    let snapshots: Vec<_> = fs::read_dir(work.join("snapshots"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(
        snapshots.iter().any(|f| f == "step-0000100.safetensors"),
        "{snapshots:?}"
    );
    let (ok_, text) = campaign(&["average", "5"], &env, &[]);
    let avg = work.join("average.safetensors");
    if snapshots.len() >= 2 {
        assert!(ok_ && text.contains("files (steps"), "{text}");
        pins::flow::weights::load(&avg, &burn::prelude::Device::flex()).unwrap();
    } else {
        assert!(!ok_ && text.contains("fewer than 2 snapshots"), "{text}");
        assert!(!avg.exists());
    }
    // The GPU mode (here on the CPU) writes the checkpoint and weights to bring back.
    fs::remove_dir_all(work.join("run")).unwrap();
    let (ok_, text) = campaign(
        &["gpu", "2", out.to_str().unwrap()],
        &env,
        &[("DEVICE", "cpu")],
    );
    assert!(ok_, "{text}");
    for f in ["state.json", "last.safetensors", "log.csv", "status.txt"] {
        assert!(out.join(f).is_file(), "{f} missing: {text}");
    }
    // Its snapshots are those of the session alone (the run was complete: none, no mean).
    assert!(!out.join("average.safetensors").exists(), "{text}");
    // Brought back to a machine whose run folder is gone, the checkpoint continues the run.
    fs::remove_dir_all(work.join("run")).unwrap();
    let gpu_out = out.as_path();
    let (ok_, text) = campaign(
        &["run", "1h"],
        &env,
        &[("CHECKPOINT", gpu_out.to_str().unwrap())],
    );
    assert!(ok_ && text.contains("starting: --resume"), "{text}");
    // A changed config refuses the campaign's weights, naming the setting.
    fs::remove_dir_all(work.join("run")).unwrap();
    let cfg = fs::read_to_string(c.join("train.json")).unwrap();
    fs::write(
        c.join("train.json"),
        cfg.replace(r#""iters": 2"#, r#""iters": 3"#),
    )
    .unwrap();
    let (ok_, text) = campaign(&["run", "1h"], &env, &[]);
    assert!(!ok_ && text.contains("iters: 2 → 3"), "{text}");
}

/// The GPU mode (here on the CPU) with COOLDOWN_MINUTES: the run trains, then a branch of it
/// cools down over as many steps as the session's mean step allows, complete within the
/// minutes; its weights and log come back beside the run's checkpoint.
/// A campaign folder of a tiny run (64×64 crops, 2 iterations) on one generated source, long
/// enough never to finish within a test.
fn tiny_campaign(c: &Path) {
    fs::create_dir_all(c.join("data")).unwrap();
    fs::write(
        c.join("train.json"),
        r#"{"model": "mms-small", "steps": 100000, "batch_size": 1, "crop": [64, 64],
            "iters": 2, "val_every": 1000, "val_max_pairs": 1, "val_iters": 2,
            "checkpoint_every": 100000}"#,
    )
    .unwrap();
    fs::write(
        c.join("data/a.json"),
        r#"{"count": 1, "seed": 1, "scene": {"kind": "chairs", "width": 80, "height": 64, "supersample": 1}}"#,
    )
    .unwrap();
    fs::write(
        c.join("stream.json"),
        r#"{"sources": [{"generator": "data/a.json", "weight": 1}]}"#,
    )
    .unwrap();
}

#[test]
fn the_campaign_script_cools_a_branch_down_in_a_gpu_session() {
    let tmp = tempfile::tempdir().unwrap();
    let (c, work, out) = (
        tmp.path().join("campaign"),
        tmp.path().join("work"),
        tmp.path().join("gpu_out"),
    );
    tiny_campaign(&c);
    let env = [("CAMPAIGN", c.as_path()), ("WORK", work.as_path())];
    let (ok_, text) = campaign(
        &["gpu", "2", s(&out)],
        &env,
        &[("DEVICE", "cpu"), ("COOLDOWN_MINUTES", "2")],
    );
    assert!(!ok_ && text.contains("COOLDOWN_MINUTES must be"), "{text}");
    let (ok_, text) = campaign(
        &["gpu", "2", s(&out)],
        &env,
        &[("DEVICE", "cpu"), ("COOLDOWN_MINUTES", "1")],
    );
    // The cool-down's steps are planned from the run's mean step; whether they all fit its
    // minute depends on the machine's load, so a cool-down stopped by its budget passes too,
    // said as such, and only a complete one must take the rate to near zero.
    let complete = text.contains("cool-down complete");
    assert!(
        ok_ && (complete || text.contains("its weights are not cooled")),
        "{text}"
    );
    let at = state_step(&work.join("run"));
    let branch = work.join(format!("cooldown-{at}"));
    let end = state_step(&branch);
    assert!(end > at, "{text}");
    let lr = log_column(&branch, 1);
    let (first, last) = (lr[at as usize], lr[lr.len() - 1]);
    let bound = if complete { 0.1 } else { 0.9 };
    assert!(last < bound * first, "{first} → {last}");
    for f in [
        "state.json",
        "last.safetensors",
        "cooldown.safetensors",
        "cooldown_log.csv",
    ] {
        assert!(out.join(f).is_file(), "{f} missing: {text}");
    }
    assert_eq!(
        fs::read(out.join("cooldown.safetensors")).unwrap(),
        fs::read(branch.join("last.safetensors")).unwrap()
    );
}

#[test]
fn the_campaign_script_ends_a_cpu_session_with_a_cool_down() {
    let tmp = tempfile::tempdir().unwrap();
    let (c, work) = (tmp.path().join("campaign"), tmp.path().join("work"));
    tiny_campaign(&c);
    let env = [("CAMPAIGN", c.as_path()), ("WORK", work.as_path())];
    let (ok_, text) = campaign(&["run", "100s"], &env, &[("COOLDOWN_MINUTES", "2")]);
    assert!(!ok_ && text.contains("leaves no time"), "{text}");
    assert!(!work.join("run").exists(), "nothing ran: {text}");
    // About 40 s of run, then a minute's cool-down of a branch, planned from the run's mean
    // step (whether it ends within its minute depends on the machine's load, so only that it
    // ran and took the rate down is asserted).
    let (ok_, text) = campaign(&["run", "130s"], &env, &[("COOLDOWN_MINUTES", "1")]);
    assert!(
        ok_ && text.contains("cooling down: --branch-from"),
        "{text}"
    );
    let at = state_step(&work.join("run"));
    let branch = work.join(format!("cooldown-{at}"));
    assert!(state_step(&branch) > at, "{text}");
    let lr = log_column(&branch, 1);
    let (first, last) = (lr[at as usize], lr[lr.len() - 1]);
    assert!(last < 0.9 * first, "{first} → {last}");
    // A run stopped before its budget (SIGTERM, as a session ends it) is not cooled down.
    use std::time::{Duration, Instant};
    let child = campaign_command(&["run", "10m"], &env, &[("COOLDOWN_MINUTES", "1")])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let (rows, t0) = (rows_or_empty(&work.join("run")).len(), Instant::now());
    while rows_or_empty(&work.join("run")).len() <= rows {
        assert!(t0.elapsed() < Duration::from_secs(600), "no step logged");
        std::thread::sleep(Duration::from_millis(50));
    }
    let pattern = format!("out {}", work.join("run").display());
    assert!(
        std::process::Command::new("pkill")
            .args(["-TERM", "-f", &pattern])
            .status()
            .unwrap()
            .success()
    );
    let out = child.wait_with_output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success()
            && text.contains("no cool-down: the run did not end at its time budget"),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(!text.contains("cooling down"), "{text}");
}
