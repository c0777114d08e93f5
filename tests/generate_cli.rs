//! End-to-end tests of `pins generate` and `pins simulate`: determinism across thread counts and
//! shards, resumption, what a scene needs, and bad input (clear error, non-zero exit, no output).

mod common;
use common::{failed, ok, pins_with_threads as pins, shared_data};

use std::collections::BTreeMap;
use std::fs;
use std::path::{Path, PathBuf};

/// All files of a folder with their bytes.
fn snapshot(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap())
        .map(|e| {
            (
                e.file_name().to_string_lossy().into_owned(),
                fs::read(e.path()).unwrap(),
            )
        })
        .collect()
}

fn write_config(dir: &Path, name: &str, json: &str) -> PathBuf {
    let p = dir.join(name);
    fs::write(&p, json).unwrap();
    p
}

const SMALL: &str = r#"{"count": 6, "seed": 42,
  "scene": {"kind": "chairs", "width": 80, "height": 64, "sprites": [2, 4], "supersample": 2}}"#;

#[test]
fn output_is_bit_identical_across_threads_and_shards() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path(), "small.json", SMALL);
    let cfg = cfg.to_str().unwrap();
    let (one, two, sharded) = (
        tmp.path().join("one"),
        tmp.path().join("two"),
        tmp.path().join("sharded"),
    );
    ok(&pins(
        &["generate", "--config", cfg, "--out", one.to_str().unwrap()],
        Some(1),
    ));
    ok(&pins(
        &["generate", "--config", cfg, "--out", two.to_str().unwrap()],
        Some(2),
    ));
    let first = ok(&pins(
        &[
            "generate",
            "--config",
            cfg,
            "--out",
            sharded.to_str().unwrap(),
            "--shard",
            "1/3",
        ],
        Some(2),
    ));
    assert!(
        first.contains("manifest.json is written when every shard"),
        "{first}"
    );
    assert!(!sharded.join("manifest.json").exists());
    for k in ["0/3", "2/3"] {
        ok(&pins(
            &[
                "generate",
                "--config",
                cfg,
                "--out",
                sharded.to_str().unwrap(),
                "--shard",
                k,
            ],
            Some(1),
        ));
    }
    let (a, b, c) = (snapshot(&one), snapshot(&two), snapshot(&sharded));
    assert_eq!(a.len(), 6 * 4 + 2, "{:?}", a.keys().collect::<Vec<_>>());
    assert_eq!(a, b, "thread count changed the bytes");
    assert_eq!(a, c, "shard split changed the bytes");
    // Another seed gives other images.
    let other = tmp.path().join("other");
    ok(&pins(
        &[
            "generate",
            "--config",
            cfg,
            "--out",
            other.to_str().unwrap(),
            "--seed",
            "43",
        ],
        None,
    ));
    assert_ne!(a["00000_img1.png"], snapshot(&other)["00000_img1.png"]);
}

#[test]
fn rerun_keeps_complete_samples_and_redoes_broken_ones() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path(), "small.json", SMALL);
    let out = tmp.path().join("ds");
    let args = [
        "generate",
        "--config",
        cfg.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    ok(&pins(&args, None));
    let before = snapshot(&out);
    // An interrupted run: one file missing, a temporary file left hours ago (stale whoever
    // wrote it), and a fresh one that may be another run's write under way (kept).
    fs::remove_file(out.join("00003_img2.png")).unwrap();
    let stale = out.join(".00004_img1.png.tmp-1-1");
    fs::write(&stale, b"partial").unwrap();
    let hours_ago = std::time::SystemTime::now() - std::time::Duration::from_secs(7 * 3600);
    fs::File::options()
        .write(true)
        .open(&stale)
        .unwrap()
        .set_modified(hours_ago)
        .unwrap();
    let fresh = out.join(".00005_img1.png.tmp-some-host-1-1");
    fs::write(&fresh, b"in flight").unwrap();
    let msg = ok(&pins(&args, None));
    assert!(
        msg.contains("5 samples kept, 0 made, 1 repaired")
            && msg.contains("00003_img2.png missing"),
        "{msg}"
    );
    assert!(!stale.exists(), "a stale temporary was kept");
    assert!(fresh.exists(), "a temporary that may be in use was removed");
    fs::remove_file(&fresh).unwrap();
    assert_eq!(snapshot(&out), before);
    // A different config must not be mixed into the same folder.
    let err = failed(&pins(
        &[
            "generate",
            "--config",
            cfg.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--seed",
            "7",
        ],
        None,
    ));
    assert!(err.contains("another config"), "{err}");
}

#[test]
fn only_what_the_scene_needs_is_written() {
    let tmp = tempfile::tempdir().unwrap();
    let still = write_config(
        tmp.path(),
        "still.json",
        r#"{"count": 2, "scene": {"kind": "chairs", "width": 48, "height": 40, "channels": 1,
            "max_translation": 0, "max_rotation_deg": 0, "scale_change": [1, 1],
            "background_translation": 0, "background_rotation_deg": 0, "background_zoom": [1, 1]},
            "camera": {"psf": "delta", "brightness": 1, "gamma": 1, "noise": {"a": 0, "b": 0}}}"#,
    );
    let out = tmp.path().join("still");
    let msg = ok(&pins(
        &[
            "generate",
            "--config",
            still.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        None,
    ));
    assert!(msg.contains("camera stages: quantize"), "{msg}");
    let files = snapshot(&out);
    assert!(
        !files.keys().any(|k| k.ends_with(".flo")),
        "a static scene wrote flow"
    );
    let img = pins::io::read_image(&out.join("00000_img1.png")).unwrap();
    assert_eq!(img.channels(), 1, "a grey scene stays one channel");
    let manifest = pins::dataset::Manifest::read(&out.join("manifest.json")).unwrap();
    assert_eq!(manifest.stages, vec!["quantize"]);
    assert!(manifest.samples.iter().all(|s| s.flow.is_none()));
}

#[test]
fn test_patterns_carry_exact_flow() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(
        tmp.path(),
        "rocket.json",
        r#"{"count": 1, "scene": {"kind": "rocket", "step": "up_right"}}"#,
    );
    let out = tmp.path().join("rocket");
    ok(&pins(
        &[
            "generate",
            "--config",
            cfg.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        None,
    ));
    let flow = pins::io::read_flo(&out.join("00000_flow.flo")).unwrap();
    assert_eq!((flow.width(), flow.height()), (701, 701));
    assert_eq!(flow.get(350, 350), (3.0, -3.0));
}

#[test]
fn real_dataset_passes_through_the_camera_keeping_its_flow() {
    let Some(data) = shared_data() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let src = data.join("flyingchairs");
    let cfg = write_config(
        tmp.path(),
        "real.json",
        &format!(
            r#"{{"count": 100, "scene": {{"kind": "dataset", "path": {:?}}}}}"#,
            src.to_str().unwrap()
        ),
    );
    let out = tmp.path().join("real");
    ok(&pins(
        &[
            "generate",
            "--config",
            cfg.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        None,
    ));
    let manifest = pins::dataset::Manifest::read(&out.join("manifest.json")).unwrap();
    assert_eq!(manifest.count, 3, "three FlyingChairs examples");
    let original = pins::io::read_flo(&src.join("0000001-gt.flo")).unwrap();
    assert_eq!(
        pins::io::read_flo(&out.join("00000_flow.flo")).unwrap(),
        original
    );
    let (clean, seen) = (
        pins::io::read_image(&src.join("0000001-img0.ppm")).unwrap(),
        pins::io::read_image(&out.join("00000_img1.png")).unwrap(),
    );
    assert_eq!(clean.shape(), seen.shape());
    let mean =
        |i: &pins::Image| i.data().iter().map(|&v| v as f64).sum::<f64>() / i.data().len() as f64;
    assert!(
        mean(&seen) < 0.8 * mean(&clean),
        "the camera dims (×0.8, γ = 1.7)"
    );
}

#[test]
fn bad_input_fails_clearly_without_output() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let out = t.join("never");
    // Unknown config key, named in the message.
    let cfg = write_config(t, "typo.json", r#"{"count": 2, "camera": {"gama": 1.2}}"#);
    let err = failed(&pins(
        &[
            "generate",
            "--config",
            cfg.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        None,
    ));
    assert!(err.contains("gama"), "{err}");
    // Bad values.
    for (json, word) in [
        (r#"{"camera": {"gamma": -1}}"#, "gamma"),
        (r#"{"camera": {"noise": {"a": -0.2}}}"#, "noise.a"),
        (r#"{"scene": {"kind": "chairs", "width": 0}}"#, "size"),
        (r#"{"camera": {"psf": "/no/such/psf.png"}}"#, "psf.png"),
        (
            r#"{"scene": {"kind": "chairs", "photos": {"dirs": ["no_such_photos"]}}}"#,
            "no_such_photos",
        ),
    ] {
        let cfg = write_config(t, "bad.json", json);
        let err = failed(&pins(
            &[
                "generate",
                "--config",
                cfg.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ],
            None,
        ));
        assert!(err.to_lowercase().contains(word), "{json}: {err}");
    }
    let err = failed(&pins(
        &["generate", "--out", out.to_str().unwrap(), "--shard", "3/2"],
        None,
    ));
    assert!(err.contains("--shard"), "{err}");
    assert!(!out.exists(), "a failed run left output behind");

    // simulate: missing image, corrupt image, bad PSF files, bad flags.
    let img_out = t.join("sim.png");
    let corrupt = t.join("corrupt.png");
    fs::write(&corrupt, b"\x89PNG\r\n\x1a\nnot really").unwrap();
    let good = t.join("good.png");
    pins::io::write_image(
        &good,
        &pins::Image::filled(3, 16, 16, 0.5),
        pins::io::BitDepth::Eight,
    )
    .unwrap();
    let mut nan = pins::Image::filled(1, 5, 5, 0.1);
    nan.set(0, 2, 2, f32::NAN);
    let nan_psf = t.join("nan_psf.npy");
    pins::io::write_npy(&nan_psf, &nan).unwrap();
    let mut neg = pins::Image::filled(1, 5, 5, 0.1);
    neg.set(0, 1, 1, -0.5);
    let neg_psf = t.join("neg_psf.npy");
    pins::io::write_npy(&neg_psf, &neg).unwrap();
    let zero_psf = t.join("zero_psf.npy");
    pins::io::write_npy(&zero_psf, &pins::Image::zeros(1, 5, 5)).unwrap();
    let o = img_out.to_str().unwrap();
    let g = good.to_str().unwrap();
    for (args, word) in [
        (
            vec!["simulate", "--in", "/no/such.png", "--out", o],
            "such.png",
        ),
        (
            vec!["simulate", "--in", corrupt.to_str().unwrap(), "--out", o],
            "corrupt.png",
        ),
        (
            vec![
                "simulate",
                "--in",
                g,
                "--out",
                o,
                "--psf",
                nan_psf.to_str().unwrap(),
            ],
            "nan",
        ),
        (
            vec![
                "simulate",
                "--in",
                g,
                "--out",
                o,
                "--psf",
                neg_psf.to_str().unwrap(),
            ],
            "neg",
        ),
        (
            vec![
                "simulate",
                "--in",
                g,
                "--out",
                o,
                "--psf",
                zero_psf.to_str().unwrap(),
            ],
            "zero",
        ),
        (
            vec!["simulate", "--in", g, "--out", o, "--gamma", "0"],
            "gamma",
        ),
        (
            vec!["simulate", "--in", g, "--out", o, "--bit-depth", "12"],
            "bit_depth",
        ),
        (
            vec!["simulate", "--in", g, "--out", o, "--noise-b", "NaN"],
            "noise.b",
        ),
    ] {
        let err = failed(&pins(&args, None));
        assert!(err.to_lowercase().contains(word), "{args:?}: {err}");
        assert!(!img_out.exists(), "{args:?} left an output file");
    }
    // And it works on good input.
    ok(&pins(
        &[
            "simulate",
            "--in",
            g,
            "--out",
            o,
            "--bit-depth",
            "16",
            "--seed",
            "3",
        ],
        None,
    ));
    assert!(img_out.exists());
}

#[test]
fn mismatched_pair_in_a_dataset_is_an_error() {
    let tmp = tempfile::tempdir().unwrap();
    let src = tmp.path().join("pairs");
    fs::create_dir_all(&src).unwrap();
    use pins::io::{BitDepth, write_image};
    write_image(
        &src.join("00001_img1.png"),
        &pins::Image::filled(3, 16, 16, 0.5),
        BitDepth::Eight,
    )
    .unwrap();
    write_image(
        &src.join("00001_img2.png"),
        &pins::Image::filled(3, 16, 20, 0.5),
        BitDepth::Eight,
    )
    .unwrap();
    let cfg = write_config(
        tmp.path(),
        "ds.json",
        &format!(
            r#"{{"scene": {{"kind": "dataset", "path": {:?}}}}}"#,
            src.to_str().unwrap()
        ),
    );
    let out = tmp.path().join("out");
    let err = failed(&pins(
        &[
            "generate",
            "--config",
            cfg.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        None,
    ));
    assert!(
        err.contains("00001_img1.png") && err.contains("00001_img2.png"),
        "{err}"
    );
    assert!(!out.join("00000_img1.png").exists());
}

/// The smallest useful config: a few 24×16 grey chairs scenes through an ideal lens with noise.
const TINY: &str = r#"{"count": 4, "seed": 1,
  "scene": {"kind": "chairs", "width": 24, "height": 16, "channels": 1, "sprites": [1, 2],
            "supersample": 1},
  "camera": {"psf": "delta"}}"#;

/// Starts `pins` with each argument list at once (no waiting in between), then collects them.
fn run_together(runs: &[Vec<String>]) -> Vec<std::process::Output> {
    let none: Vec<(String, String)> = Vec::new();
    run_together_env(
        &runs
            .iter()
            .map(|a| (a.clone(), none.clone()))
            .collect::<Vec<_>>(),
    )
}

/// A run's arguments and its extra environment variables.
type EnvRun = (Vec<String>, Vec<(String, String)>);

/// As `run_together`, each run with its own extra environment variables.
fn run_together_env(runs: &[EnvRun]) -> Vec<std::process::Output> {
    use std::process::{Command, Stdio};
    let children: Vec<_> = runs
        .iter()
        .map(|(args, env)| {
            Command::new(env!("CARGO_BIN_EXE_pins"))
                .args(args)
                .envs(env.iter().map(|(k, v)| (k.as_str(), v.as_str())))
                .env("RAYON_NUM_THREADS", "1")
                .stdout(Stdio::piped())
                .stderr(Stdio::piped())
                .spawn()
                .expect("start pins")
        })
        .collect();
    children
        .into_iter()
        .map(|c| c.wait_with_output().expect("wait for pins"))
        .collect()
}

fn generate_args(cfg: &Path, out: &Path, extra: &[&str]) -> Vec<String> {
    let mut v: Vec<String> = ["generate", "--quiet", "--config"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    v.push(cfg.to_str().unwrap().into());
    v.push("--out".into());
    v.push(out.to_str().unwrap().into());
    v.extend(extra.iter().map(|s| s.to_string()));
    v
}

#[test]
fn racing_runs_of_different_configs_leave_exactly_one_owner() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path(), "tiny.json", TINY);
    let seeds = ["1", "9", "17"];
    // What each config alone makes.
    let reference: Vec<_> = seeds
        .iter()
        .map(|s| {
            let out = tmp.path().join(format!("ref{s}"));
            ok(&pins(
                &generate_args(&cfg, &out, &["--seed", s])
                    .iter()
                    .map(String::as_str)
                    .collect::<Vec<_>>(),
                Some(1),
            ));
            snapshot(&out)
        })
        .collect();
    for round in 0..30 {
        let out = tmp.path().join(format!("race{round}"));
        let runs: Vec<_> = seeds
            .iter()
            .map(|s| generate_args(&cfg, &out, &["--seed", s]))
            .collect();
        let outs = run_together(&runs);
        let winners: Vec<usize> = (0..outs.len())
            .filter(|&k| outs[k].status.success())
            .collect();
        let report = |k: usize| String::from_utf8_lossy(&outs[k].stderr).into_owned();
        assert_eq!(
            winners.len(),
            1,
            "round {round}: {} runs succeeded; stderr: {:?}",
            winners.len(),
            (0..outs.len()).map(report).collect::<Vec<_>>()
        );
        for k in (0..outs.len()).filter(|k| !winners.contains(k)) {
            let err = report(k);
            assert!(
                err.contains("another config") && err.contains(out.to_str().unwrap()),
                "round {round}: {err}"
            );
        }
        assert!(
            snapshot(&out) == reference[winners[0]],
            "round {round}: the folder is not exactly what seed {} alone makes",
            seeds[winners[0]]
        );
    }
}

#[test]
fn shards_started_together_make_what_one_run_makes() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path(), "tiny.json", TINY);
    let one = tmp.path().join("one");
    let single = generate_args(&cfg, &one, &["--count", "8"]);
    ok(&pins(
        &single.iter().map(String::as_str).collect::<Vec<_>>(),
        Some(1),
    ));
    let reference = snapshot(&one);
    assert_eq!(reference.len(), 8 * 4 + 2);
    for round in 0..6 {
        let out = tmp.path().join(format!("sharded{round}"));
        let runs: Vec<_> = (0..4)
            .map(|k| generate_args(&cfg, &out, &["--count", "8", "--shard", &format!("{k}/4")]))
            .collect();
        for (k, o) in run_together(&runs).iter().enumerate() {
            assert!(
                o.status.success(),
                "round {round}, shard {k}/4: {}",
                String::from_utf8_lossy(&o.stderr)
            );
        }
        assert!(
            snapshot(&out) == reference,
            "round {round}: shards together differ from one run: {:?}",
            snapshot(&out).keys().collect::<Vec<_>>()
        );
    }
}

/// Cluster array jobs: the tasks of a Slurm array starting at 1 with a step of 2, and the pods
/// of a Kubernetes Indexed Job, started together on one folder with only their scheduler's
/// environment, make what one run makes; each says where its shard came from.
#[test]
fn scheduler_array_tasks_make_what_one_run_makes() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path(), "tiny.json", TINY);
    let one = tmp.path().join("one");
    let single = generate_args(&cfg, &one, &["--count", "9"]);
    ok(&pins(
        &single.iter().map(String::as_str).collect::<Vec<_>>(),
        Some(1),
    ));
    let reference = snapshot(&one);
    let kv = |pairs: &[(&str, String)]| -> Vec<(String, String)> {
        pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.clone()))
            .collect()
    };
    // sbatch --array=1-5:2 → tasks 1, 3, 5.
    let slurm_out = tmp.path().join("slurm");
    let slurm: Vec<_> = [1, 3, 5]
        .iter()
        .map(|id| {
            (
                generate_args(&cfg, &slurm_out, &["--count", "9"]),
                kv(&[
                    ("SLURM_ARRAY_TASK_ID", id.to_string()),
                    ("SLURM_ARRAY_TASK_MIN", "1".into()),
                    ("SLURM_ARRAY_TASK_MAX", "5".into()),
                    ("SLURM_ARRAY_TASK_STEP", "2".into()),
                    ("SLURM_ARRAY_TASK_COUNT", "3".into()),
                ]),
            )
        })
        .collect();
    // An Indexed Job of 4 completions, the count from PINS_SHARD_COUNT for two pods and
    // --shards for the others.
    let k8s_out = tmp.path().join("k8s");
    let k8s: Vec<_> = (0..4)
        .map(|i| {
            let mut args = generate_args(&cfg, &k8s_out, &["--count", "9"]);
            let mut env = kv(&[("JOB_COMPLETION_INDEX", i.to_string())]);
            if i % 2 == 0 {
                env.push(("PINS_SHARD_COUNT".into(), "4".into()));
            } else {
                args.extend(["--shards".to_string(), "4".to_string()]);
            }
            (args, env)
        })
        .collect();
    for (name, runs, out, n) in [("slurm", slurm, &slurm_out, 3), ("k8s", k8s, &k8s_out, 4)] {
        let outs = run_together_env(&runs);
        for (k, o) in outs.iter().enumerate() {
            let err = String::from_utf8_lossy(&o.stderr);
            assert!(o.status.success(), "{name} task {k}: {err}");
            assert!(
                err.contains(&format!("shard {k}/{n} from the")),
                "{name} {k}: {err}"
            );
        }
        assert!(
            snapshot(out) == reference,
            "{name}: the array's tasks differ from one run"
        );
    }
    // The shipped sbatch script, run as two tasks of `--array=0-1` would run it.
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/generate_slurm.sbatch");
    let script_out = tmp.path().join("script");
    let small_cfg = write_config(
        tmp.path(),
        "nine.json",
        &TINY.replacen("\"count\": 4", "\"count\": 9", 1),
    );
    for id in ["0", "1"] {
        let o = std::process::Command::new("bash")
            .arg(&script)
            .arg(&small_cfg)
            .arg(&script_out)
            .env("PINS", env!("CARGO_BIN_EXE_pins"))
            .env("SLURM_ARRAY_TASK_ID", id)
            .env("SLURM_ARRAY_TASK_MIN", "0")
            .env("SLURM_ARRAY_TASK_MAX", "1")
            .env("SLURM_ARRAY_TASK_COUNT", "2")
            .env("SLURM_CPUS_PER_TASK", "1")
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    assert!(
        snapshot(&script_out) == reference,
        "the sbatch script's tasks"
    );
    // The Kubernetes manifest repeats its completions in PINS_SHARD_COUNT.
    let job = fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/generate_k8s_job.yaml"),
    )
    .unwrap();
    let field = |key: &str| {
        job.lines()
            .filter(|l| !l.trim_start().starts_with('#'))
            .skip_while(|l| !l.contains(key))
            .find_map(|l| {
                let digits: String = l
                    .split('#')
                    .next()
                    .unwrap_or("")
                    .chars()
                    .filter(char::is_ascii_digit)
                    .collect();
                digits.parse::<usize>().ok()
            })
            .unwrap_or_else(|| panic!("{key} in the manifest"))
    };
    assert_eq!(field("completions:"), field("PINS_SHARD_COUNT"));
    assert!(job.contains("completionMode: Indexed"));
    // A Kubernetes index without a count is refused before anything is written.
    let bad = tmp.path().join("bad");
    let o = run_together_env(&[(
        generate_args(&cfg, &bad, &["--count", "9"]),
        kv(&[("JOB_COMPLETION_INDEX", "1".into())]),
    )]);
    let err = String::from_utf8_lossy(&o[0].stderr);
    assert!(
        !o[0].status.success() && err.contains("PINS_SHARD_COUNT"),
        "{err}"
    );
    assert!(!bad.exists());
}

/// A `NNNNN_meta.json` as older versions wrote it: bare file names, no sizes or hashes.
fn old_format_meta(path: &Path) {
    let mut v: serde_json::Value = serde_json::from_slice(&fs::read(path).unwrap()).unwrap();
    let names: Vec<serde_json::Value> = v["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["name"].clone())
        .collect();
    v["files"] = serde_json::Value::Array(names);
    fs::write(path, v.to_string()).unwrap();
}

#[test]
fn damaged_samples_are_found_by_verify_and_repaired_bit_identically() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path(), "small.json", SMALL);
    let out = tmp.path().join("ds");
    let gen_args = generate_args(&cfg, &out, &["--count", "8"]);
    let gen_args: Vec<&str> = gen_args.iter().map(String::as_str).collect();
    let verify = ["generate", "--verify", "--out", out.to_str().unwrap()];
    ok(&pins(&gen_args, None));
    let before = snapshot(&out);
    let msg = ok(&pins(&verify, None));
    assert!(
        msg.contains("8 of 8 samples verified (24 files") && msg.contains("manifest.json agrees"),
        "{msg}"
    );
    // Every meta records each file's size and SHA-256, and the manifest lists the same.
    let meta: serde_json::Value = serde_json::from_slice(&before["00002_meta.json"]).unwrap();
    let flo = &meta["files"][2];
    assert_eq!(flo["name"], "00002_flow.flo");
    assert_eq!(flo["bytes"], before["00002_flow.flo"].len());
    assert_eq!(flo["sha256"].as_str().unwrap().len(), 64);

    // Damage of every kind: truncated, emptied, altered in the middle (same size), all gone,
    // an older meta without hashes, an unparsable meta, a missing meta (interrupted write).
    let img1 = before["00000_img1.png"].len();
    fs::write(out.join("00000_img1.png"), &before["00000_img1.png"][..412]).unwrap();
    fs::write(out.join("00001_flow.flo"), b"").unwrap();
    let mut altered = before["00002_img2.png"].clone();
    let mid = altered.len() / 2;
    altered[mid] ^= 0xff;
    fs::write(out.join("00002_img2.png"), &altered).unwrap();
    for f in ["img1.png", "img2.png", "flow.flo", "meta.json"] {
        fs::remove_file(out.join(format!("00003_{f}"))).unwrap();
    }
    old_format_meta(&out.join("00004_meta.json"));
    fs::write(out.join("00005_meta.json"), b"{\"index\": 5, ").unwrap();
    fs::remove_file(out.join("00006_meta.json")).unwrap();
    let damaged = snapshot(&out);
    let stamp = |p: &Path| fs::metadata(p).unwrap().modified().unwrap();
    let dir_stamp = stamp(&out);

    let err = failed(&pins(&verify, None));
    for expected in [
        format!("00000: 00000_img1.png truncated (412 of {img1} bytes)"),
        format!(
            "00001: 00001_flow.flo truncated (0 of {} bytes)",
            before["00001_flow.flo"].len()
        ),
        "00002: 00002_img2.png does not match its hash".into(),
        "00003: missing".into(),
        "00004: metadata of an older format, without file hashes".into(),
        "00005: metadata does not parse".into(),
        "00006: metadata missing".into(),
        "7 of 8 samples are bad".into(),
    ] {
        assert!(err.contains(&expected), "{expected:?} not in: {err}");
    }
    assert!(!err.contains("00007"), "{err}");
    // --verify wrote nothing: not a byte, not a temporary (which would touch the folder).
    assert_eq!(snapshot(&out), damaged);
    assert_eq!(stamp(&out), dir_stamp, "--verify created or removed a file");

    // A rerun redoes exactly the broken samples, bit-identical to the first run.
    let msg = ok(&pins(&gen_args, None));
    assert!(msg.contains("1 samples kept, 1 made, 6 repaired"), "{msg}");
    assert!(
        msg.contains("repaired 00002: 00002_img2.png does not match its hash"),
        "{msg}"
    );
    assert!(
        snapshot(&out) == before,
        "repaired samples differ from a fresh run"
    );
    ok(&pins(&verify, None));

    // The manifest must agree with the metas.
    let manifest = out.join("manifest.json");
    let text = String::from_utf8(before["manifest.json"].clone()).unwrap();
    let sha = meta["files"][2]["sha256"].as_str().unwrap();
    fs::write(&manifest, text.replace(sha, &"0".repeat(64))).unwrap();
    let err = failed(&pins(&verify, None));
    assert!(
        err.contains("manifest.json: disagrees with the metadata of sample 00002"),
        "{err}"
    );
    // A rerun rewrites it.
    ok(&pins(&gen_args, None));
    assert!(snapshot(&out) == before);

    // --config/--count/--seed with --verify must be the folder's config.
    let c = cfg.to_str().unwrap();
    let o = out.to_str().unwrap();
    ok(&pins(
        &[
            "generate", "--verify", "--out", o, "--config", c, "--count", "8",
        ],
        None,
    ));
    ok(&pins(
        &["generate", "--verify", "--out", o, "--seed", "42"],
        None,
    ));
    for extra in [&["--seed", "43"][..], &["--config", c]] {
        let mut args = vec!["generate", "--verify", "--out", o];
        args.extend_from_slice(extra);
        let err = failed(&pins(&args, None));
        assert!(err.contains("another config"), "{extra:?}: {err}");
    }
    let err = failed(&pins(
        &["generate", "--verify", "--out", o, "--shard", "0/2"],
        None,
    ));
    assert!(err.contains("--shard"), "{err}");
    // Not a dataset folder: an error naming it, and nothing created.
    let none = tmp.path().join("nothing");
    let err = failed(&pins(
        &["generate", "--verify", "--out", none.to_str().unwrap()],
        None,
    ));
    assert!(err.contains("nothing"), "{err}");
    assert!(!none.exists());
    let err = failed(&pins(
        &[
            "generate",
            "--verify",
            "--out",
            tmp.path().to_str().unwrap(),
        ],
        None,
    ));
    assert!(err.contains("config.json"), "{err}");
}
