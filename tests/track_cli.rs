//! `pins track` on a folder of flows: IDs, predictions at the horizons, and bad input.

use std::path::Path;
use std::process::Command;

use pins::Flow;

mod common;
use common::{failed, ok, pins};

/// A square of `side` px moving by (vx, vy) per frame from (x0, y0), as a flow map.
fn square_flow(h: usize, w: usize, objects: &[(f64, f64, f32, f32)], n: usize) -> Flow {
    let mut f = Flow::zeros(h, w);
    for &(x0, y0, vx, vy) in objects {
        let (cx, cy) = (x0 + vx as f64 * n as f64, y0 + vy as f64 * n as f64);
        for y in 0..h {
            for x in 0..w {
                if (x as f64 - cx).abs() <= 4.0 && (y as f64 - cy).abs() <= 4.0 {
                    f.set(y, x, vx, vy);
                }
            }
        }
    }
    f
}

#[test]
fn tracks_two_objects_and_rejects_bad_folders() {
    let d = tempfile::tempdir().unwrap();
    let flows = d.path().join("flows");
    for n in 0..40 {
        let f = square_flow(
            120,
            200,
            &[(20.0, 30.0, 3.0, 0.5), (180.0, 90.0, -2.0, -1.0)],
            n,
        );
        pins::io::write_flo(&flows.join(format!("{n:04}.flo")), &f).unwrap();
    }
    let out = d.path().join("out");
    let o = Command::new(env!("CARGO_BIN_EXE_pins"))
        .args([
            "track",
            "--flows",
            flows.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--horizons",
            "1,5",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("tracks.json")).unwrap()).unwrap();
    let objects = v["objects"].as_array().unwrap();
    assert_eq!(objects.len(), 2, "{v}");
    let last = objects[0]["frames"]
        .as_array()
        .unwrap()
        .last()
        .unwrap()
        .clone();
    let (x, p5) = (
        last["centroid"][0].as_f64().unwrap(),
        last["predicted"]["5"][0].as_f64().unwrap(),
    );
    assert!(
        (p5 - x - 15.0).abs() < 2.0,
        "5 frames at 3 px/frame: {x} → {p5}"
    );

    // A flow of another size in the sequence.
    pins::io::write_flo(&flows.join("0099.flo"), &Flow::zeros(60, 80)).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_pins"))
        .args([
            "track",
            "--flows",
            flows.to_str().unwrap(),
            "--out",
            d.path().join("x").to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("0099.flo"));
    assert!(!d.path().join("x").join("tracks.json").exists());

    // Bad settings in a config file are refused, naming the file and the key, before any
    // output: alignment weights (three, finite, non-negative, not all zero), the fits' samples
    // per order (at least 1), the trend's reach and the split's separation (non-negative), an
    // unknown key, and a bad value given by a flag.
    let config = d.path().join("settings.json");
    for (text, flags, says) in [
        (
            r#"{"detect": {"align_weights": [1, 2]}}"#,
            &[][..],
            "detect.align_weights",
        ),
        (
            r#"{"detect": {"align_weights": [1, -1, 1]}}"#,
            &[],
            "align_weights",
        ),
        (
            r#"{"detect": {"align_weights": [0, 0, 0]}}"#,
            &[],
            "align_weights",
        ),
        (
            r#"{"tracker": {"mtp": {"samples_per_order": 0}}}"#,
            &[],
            "samples_per_order",
        ),
        (
            r#"{"tracker": {"mtp": {"trend_reach": -1}}}"#,
            &[],
            "mtp.trend_reach",
        ),
        (
            r#"{"detect": {"place": {"split": -0.5}}}"#,
            &[],
            "detect.place.split",
        ),
        (r#"{"tracker": {"confirmm": 3}}"#, &[], "tracker.confirmm"),
        (
            r#"{"profile": "exact"}"#,
            &["--confirm", "0"],
            "tracker.confirm",
        ),
        (r#"{"profile": "exact"}"#, &["--horizons", "0"], "horizons"),
        (
            r#"{"profile": "exact"}"#,
            &["--profile", "mms"],
            "exact or estimated",
        ),
    ] {
        std::fs::write(&config, text).unwrap();
        let out = d.path().join("refused");
        let o = Command::new(env!("CARGO_BIN_EXE_pins"))
            .args(["track", "--flows", flows.to_str().unwrap(), "--out"])
            .arg(&out)
            .arg("--config")
            .arg(&config)
            .args(flags)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(says), "{text}: {err}");
        if flags.is_empty() {
            assert!(err.contains("settings.json"), "{text}: {err}");
        }
        assert!(!out.exists(), "{text}");
    }
}

/// The flags override the config file, which overrides the profile: `--confirm 2` gives the
/// tracks of the file that says it, and without it the profile's 5 hits report fewer frames.
#[test]
fn flags_override_the_config_file() {
    let d = tempfile::tempdir().unwrap();
    let flows = d.path().join("flows");
    for n in 0..20 {
        let f = square_flow(60, 100, &[(20.0, 30.0, 3.0, 0.0)], n);
        pins::io::write_flo(&flows.join(format!("{n:04}.flo")), &f).unwrap();
    }
    let run = |name: &str, config: &str, flags: &[&str]| {
        let file = d.path().join(format!("{name}.json"));
        std::fs::write(&file, config).unwrap();
        let out = d.path().join(name);
        ok(&pins(
            &[
                &[
                    "track",
                    "--flows",
                    flows.to_str().unwrap(),
                    "--out",
                    out.to_str().unwrap(),
                    "--no-plots",
                    "--config",
                    file.to_str().unwrap(),
                ],
                flags,
            ]
            .concat(),
        ));
        let mut v = json(&out.join("tracks.json"));
        v["ms_per_frame"] = serde_json::Value::Null;
        v
    };
    let two = run(
        "two",
        r#"{"tracker": {"confirm": 2}, "horizons": [1, 5]}"#,
        &[],
    );
    let flag = run("flag", r#"{"horizons": [1, 5]}"#, &["--confirm", "2"]);
    assert_eq!(two, flag);
    let five = run("five", r#"{"horizons": [1, 5]}"#, &["--profile", "exact"]);
    let frames = |v: &serde_json::Value| v["objects"][0]["frames"].as_array().map(Vec::len);
    assert!(
        frames(&two) > frames(&five),
        "confirmed after 2 hits, not 5: {two} {five}"
    );
}

/// Writes a clip config and renders it with `pins track render`.
fn render(dir: &Path, scene: serde_json::Value) -> std::path::PathBuf {
    let cfg = dir.join("clip.json");
    std::fs::write(&cfg, serde_json::json!({ "scene": scene }).to_string()).unwrap();
    let out = dir.join("clip");
    ok(&pins(&[
        "track",
        "render",
        "--config",
        cfg.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]));
    out
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
fn crossing_objects_keep_their_ids_and_are_scored_per_horizon() {
    let d = tempfile::tempdir().unwrap();
    // Two discs on straight lines that cross (one passes in front of the other, so their
    // regions merge and split), and a third that enters from the right and leaves at the left.
    let clip = render(
        d.path(),
        serde_json::json!({
            "width": 200, "height": 120, "frames": 60, "seed": 3,
            "objects": [
                {"path": "line", "radius": 8, "from": [0.1, 0.3], "to": [0.9, 0.7]},
                {"path": "line", "radius": 8, "from": [0.1, 0.7], "to": [0.9, 0.3]},
                {"path": "line", "radius": 7, "from": [1.1, 0.15], "to": [-0.1, 0.15]}
            ]
        }),
    );
    assert_eq!(std::fs::read_dir(clip.join("frames")).unwrap().count(), 60);
    // Rendering another clip into the same folder is refused; the same clip again is fine.
    let other = d.path().join("other.json");
    std::fs::write(
        &other,
        r#"{"scene": {"width": 64, "height": 48, "frames": 3}}"#,
    )
    .unwrap();
    let err = failed(&pins(&[
        "track",
        "render",
        "--config",
        other.to_str().unwrap(),
        "--out",
        clip.to_str().unwrap(),
    ]));
    assert!(err.contains("another clip"), "{err}");
    assert_eq!(std::fs::read_dir(clip.join("frames")).unwrap().count(), 60);
    assert_eq!(std::fs::read_dir(clip.join("flows")).unwrap().count(), 59);
    let truth = json(&clip.join("truth.json"));
    assert_eq!(truth["objects"][2]["visible"][0], false);
    assert_eq!(truth["objects"][2]["visible"][30], true);

    let out = d.path().join("tracked");
    let truth_path = clip.join("truth.json");
    ok(&pins(&[
        "track",
        "--flows",
        clip.join("flows").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--truth",
        truth_path.to_str().unwrap(),
        "--horizons",
        "1,10",
    ]));
    let tracks = json(&out.join("tracks.json"));
    assert_eq!(tracks["objects"].as_array().unwrap().len(), 3, "{tracks}");
    for o in tracks["objects"].as_array().unwrap() {
        assert!(out.join(format!("plot_id{}.png", o["id"])).exists());
        for f in o["frames"].as_array().unwrap() {
            for p in f["predicted"].as_object().unwrap().values() {
                assert!(p[0].as_f64().unwrap().is_finite() && p[1].as_f64().unwrap().is_finite());
            }
        }
    }
    let report_path = d.path().join("report.json");
    let table = ok(&pins(&[
        "track",
        "eval",
        "--tracks",
        out.join("tracks.json").to_str().unwrap(),
        "--truth",
        truth_path.to_str().unwrap(),
        "--out",
        report_path.to_str().unwrap(),
    ]));
    assert!(table.contains("RMSE_2D"), "{table}");
    let r = json(&report_path);
    assert_eq!(r["id_switches"], 0, "{table}");
    assert_eq!(r["missed"].as_array().unwrap().len(), 0, "{table}");
    for o in r["objects"].as_array().unwrap() {
        assert!(
            o["truth_index"].is_u64(),
            "every track follows an object: {table}"
        );
        // Straight lines at constant speed from exact flow: sub-pixel one frame ahead.
        let h1 = &o["horizons"][0];
        assert_eq!(h1["horizon"], 1);
        assert!(h1["rmse_2d"].as_f64().unwrap() < 1.0, "{table}");
    }

    // A truth of another clip length is refused by name.
    let mut bad = truth.clone();
    bad["frames"] = serde_json::json!(61);
    let bad_path = d.path().join("bad_truth.json");
    std::fs::write(&bad_path, bad.to_string()).unwrap();
    let err = failed(&pins(&[
        "track",
        "eval",
        "--tracks",
        out.join("tracks.json").to_str().unwrap(),
        "--truth",
        bad_path.to_str().unwrap(),
    ]));
    assert!(err.contains("bad_truth.json"), "{err}");
}

#[test]
fn frames_are_tracked_through_the_shipped_network() {
    let d = tempfile::tempdir().unwrap();
    let clip = render(
        d.path(),
        serde_json::json!({
            "width": 96, "height": 64, "frames": 5, "seed": 4,
            "objects": [{"path": "line", "radius": 8, "from": [0.3, 0.5], "to": [0.7, 0.5]}]
        }),
    );
    let out = d.path().join("tracked");
    let msg = ok(&pins(&[
        "track",
        "--frames",
        clip.join("frames").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--iters",
        "4",
        "--horizons",
        "1,2",
    ]));
    assert!(msg.contains("MMS flow"), "{msg}");
    let tracks = json(&out.join("tracks.json"));
    assert!(tracks["objects"].is_array() && tracks["ms_per_frame"].as_f64().is_some());
    // --flows and --frames together: the flows are read, the frames feed the photometric
    // test; a frame count that does not fit the flows is refused.
    ok(&pins(&[
        "track",
        "--frames",
        clip.join("frames").to_str().unwrap(),
        "--flows",
        clip.join("flows").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]));
    let few = d.path().join("few");
    std::fs::create_dir_all(&few).unwrap();
    for f in ["00000.png", "00001.png"] {
        std::fs::copy(clip.join("frames").join(f), few.join(f)).unwrap();
    }
    let msg = failed(&pins(&[
        "track",
        "--frames",
        few.to_str().unwrap(),
        "--flows",
        clip.join("flows").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]));
    assert!(msg.contains("need one frame more than flows"), "{msg}");
}

#[test]
fn leaving_and_reentering_still_objects_and_bad_flows() {
    let d = tempfile::tempdir().unwrap();
    let flows = d.path().join("flows");
    // Moving right for 15 frames, gone (still: zero flow) for 10, then back moving left at ±π.
    for n in 0..40 {
        let f = if n < 15 {
            square_flow(80, 120, &[(20.0, 40.0, 4.0, 0.0)], n)
        } else if n < 25 {
            Flow::zeros(80, 120)
        } else {
            square_flow(80, 120, &[(110.0, 40.0, -4.0, 0.0)], n - 25)
        };
        pins::io::write_flo(&flows.join(format!("{n:04}.flo")), &f).unwrap();
    }
    let out = d.path().join("out");
    ok(&pins(&[
        "track",
        "--flows",
        flows.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--horizons",
        "1,30",
        "--no-plots",
    ]));
    let tracks = json(&out.join("tracks.json"));
    let last = tracks["objects"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|o| o["frames"].as_array().unwrap().clone())
        .max_by_key(|f| f["frame"].as_u64().unwrap())
        .unwrap();
    // The last prediction points left: the wrap-around at ±π did not flip it.
    assert!(
        last["predicted"]["30"][0].as_f64().unwrap() < last["centroid"][0].as_f64().unwrap(),
        "{last}"
    );
    assert!(!out.join("plot_id1.png").exists(), "--no-plots");

    // A flow with an unknown (NaN) vector: an invalid pixel, tracking goes on.
    let mut f = Flow::zeros(80, 120);
    f.set(3, 4, f32::NAN, 0.0);
    pins::io::write_flo(&flows.join("0040.flo"), &f).unwrap();
    let x = d.path().join("x");
    ok(&pins(&[
        "track",
        "--flows",
        flows.to_str().unwrap(),
        "--out",
        x.to_str().unwrap(),
        "--no-plots",
    ]));
    assert!(x.join("tracks.json").is_file());
    // A truncated flow file: a clear error naming the file, no output.
    let bytes = std::fs::read(flows.join("0040.flo")).unwrap();
    std::fs::write(flows.join("0040.flo"), &bytes[..100]).unwrap();
    let y = d.path().join("y");
    let err = failed(&pins(&[
        "track",
        "--flows",
        flows.to_str().unwrap(),
        "--out",
        y.to_str().unwrap(),
    ]));
    assert!(
        err.contains("0040.flo") && err.contains("truncated"),
        "{err}"
    );
    assert!(!y.join("tracks.json").exists());
    // A bad clip config names the key.
    let cfg = d.path().join("clip.json");
    std::fs::write(&cfg, r#"{"scene": {"frames": 1}}"#).unwrap();
    let err = failed(&pins(&[
        "track",
        "render",
        "--config",
        cfg.to_str().unwrap(),
        "--out",
        d.path().join("r").to_str().unwrap(),
    ]));
    assert!(err.contains("frames"), "{err}");
    assert!(!d.path().join("r").join("truth.json").exists());
}

#[test]
fn an_experiment_scores_every_predictor_and_the_fit_wins_on_a_spiral() {
    let d = tempfile::tempdir().unwrap();
    std::fs::write(
        d.path().join("spiral.json"),
        r#"{"scene": {"width": 240, "height": 180, "frames": 90, "seed": 5,
            "objects": [{"path": "spiral", "radius": 8, "start": 0.5}]}}"#,
    )
    .unwrap();
    let cfg = d.path().join("exp.json");
    std::fs::write(
        &cfg,
        r#"{"clips": [{"name": "spiral", "config": "spiral.json"}],
            "predictors": [
              {"name": "poly", "mtp": {"method": "poly", "order": 2, "window": 30}},
              {"name": "cv", "mtp": {"method": "constant_velocity"}}],
            "horizons": [1, 15]}"#,
    )
    .unwrap();
    let out = d.path().join("out");
    let table = ok(&pins(&[
        "track",
        "experiment",
        "--config",
        cfg.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]));
    assert!(table.contains("RMSE_2D"), "{table}");
    let r = json(&out.join("report.json"));
    let pooled = |p: &str, h: u64| {
        r["rows"]
            .as_array()
            .unwrap()
            .iter()
            .find(|row| row["predictor"] == p && row["object"].is_null() && row["horizon"] == h)
            .unwrap_or_else(|| panic!("no row for {p} at {h}: {table}"))["rmse_2d"]
            .as_f64()
            .unwrap()
    };
    // A steadily turning path: the polynomial forecast beats constant velocity 15 frames out.
    assert!(pooled("poly", 15) < 0.5 * pooled("cv", 15), "{table}");
    assert!(pooled("poly", 1) < 2.0 && pooled("cv", 1) < 2.0, "{table}");
    assert!(out.join("plots").join("spiral_poly_id1.png").exists());
    // An unknown predictor key is named.
    std::fs::write(
        &cfg,
        r#"{"clips": [{"name": "s", "config": "spiral.json"}],
            "predictors": [{"name": "p", "mtp": {"windw": 3}}], "horizons": [1]}"#,
    )
    .unwrap();
    let err = failed(&pins(&[
        "track",
        "experiment",
        "--config",
        cfg.to_str().unwrap(),
        "--out",
        d.path().join("x").to_str().unwrap(),
    ]));
    assert!(err.contains("windw"), "{err}");
}

/// The whole system's error against run time: an MMS experiment with two operating points
/// (full and half resolution) gives one point row each, with the flow and tracking times, the
/// pooled error per horizon and the chart; operating points without MMS, or a scale outside
/// (0, 1], are refused by name, as is `pins track --scale 0`.
#[test]
fn operating_points_give_the_error_against_run_time() {
    let d = tempfile::tempdir().unwrap();
    std::fs::write(
        d.path().join("line.json"),
        r#"{"scene": {"width": 128, "height": 96, "frames": 10, "seed": 3,
            "objects": [{"path": "line", "radius": 12, "from": [0.25, 0.5], "to": [0.75, 0.5]}]}}"#,
    )
    .unwrap();
    let cfg = d.path().join("exp.json");
    let write = |extra: &str| {
        std::fs::write(
            &cfg,
            format!(
                r#"{{"clips": [{{"name": "line", "config": "line.json"}}],
                    "predictors": [{{"name": "cv", "mtp": {{"method": "constant_velocity"}}}}],
                    "horizons": [1, 2], {extra}}}"#
            ),
        )
        .unwrap();
    };
    write(
        r#""flow": "mms", "track": {"tracker": {"confirm": 2}},
           "operating_points": [{"scale": 1.0, "iters": 2}, {"scale": 0.5, "iters": 3},
                                {"scale": 1.5, "iters": 2}]"#,
    );
    let out = d.path().join("out");
    let table = ok(&pins(&[
        "track",
        "experiment",
        "--config",
        cfg.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--no-plots",
    ]));
    assert!(table.contains("total ms"), "{table}");
    let r = json(&out.join("report.json"));
    let points = r["points"].as_array().expect("points");
    assert_eq!(points.len(), 3, "{table}");
    for (p, (scale, iters)) in points.iter().zip([(1.0, 2), (0.5, 3), (1.5, 2)]) {
        assert_eq!(p["point"]["scale"].as_f64(), Some(scale));
        assert_eq!(p["point"]["iters"].as_u64(), Some(iters));
        assert!(p["flow_ms_per_frame"].as_f64().unwrap() > 0.0, "{p}");
        assert_eq!(p["rmse_2d"].as_array().unwrap().len(), 2, "{p}");
    }
    // Each case is its own predictor name in the per-case summaries.
    assert!(
        r["id_switches"]
            .as_array()
            .unwrap()
            .iter()
            .any(|row| row[1] == "cv @ scale 0.50, 3 it"),
        "{table}"
    );
    // The chart is drawn wherever a track reached the horizon.
    let finite = points
        .iter()
        .any(|p| p["rmse_2d"][0][1].as_f64().is_some_and(f64::is_finite));
    assert_eq!(out.join("error_vs_ms_h1.png").exists(), finite, "{table}");
    for (extra, named) in [
        (
            r#""operating_points": [{"scale": 1.0, "iters": 2}]"#,
            "only MMS",
        ),
        (
            r#""flow": "mms", "operating_points": [{"scale": 4.5, "iters": 2}]"#,
            "must be in (0, 4]",
        ),
        (
            r#""track": {"flow": {"scale": 1.5}}"#,
            "only MMS flow runs at a scale",
        ),
        (
            r#""flow": "mms", "track": {"flow": {"scale": 0}}"#,
            "must be in (0, 4]",
        ),
        (
            r#""track": {"tracker": {"max_gate_factor": 0.5}}"#,
            "tracker.max_gate_factor",
        ),
        (
            r#""track": {"tracker": {"confrm": 2}}"#,
            "track.tracker.confrm",
        ),
        (r#""confirm": 2"#, "unknown field `confirm`"),
        (
            r#""flow": "mms", "operating_points": [{"scale": 0.5, "iters": 0}]"#,
            "iters must be",
        ),
    ] {
        write(extra);
        let err = failed(&pins(&[
            "track",
            "experiment",
            "--config",
            cfg.to_str().unwrap(),
            "--out",
            d.path().join("x").to_str().unwrap(),
        ]));
        assert!(err.contains(named), "{extra}: {err}");
    }
    let err = failed(&pins(&[
        "track",
        "--frames",
        d.path().to_str().unwrap(),
        "--scale",
        "0",
        "--out",
        d.path().join("y").to_str().unwrap(),
    ]));
    assert!(err.contains("--scale"), "{err}");
}

/// The peer row: a tracking experiment on OpenCV's DIS flow of the clip's camera frames tracks
/// the disc and reports DIS's time per frame (where Python has OpenCV; elsewhere the run fails
/// with a message naming the DIS script, and the test says it could not check more).
#[test]
fn a_dis_experiment_tracks_on_the_peer_flow() {
    let d = tempfile::tempdir().unwrap();
    std::fs::write(
        d.path().join("line.json"),
        r#"{"scene": {"width": 256, "height": 192, "frames": 20, "seed": 4,
            "objects": [{"path": "line", "radius": 16, "from": [0.3, 0.5], "to": [0.7, 0.5]}]}}"#,
    )
    .unwrap();
    let cfg = d.path().join("exp.json");
    std::fs::write(
        &cfg,
        r#"{"clips": [{"name": "line", "config": "line.json"}],
            "predictors": [{"name": "cv", "mtp": {"method": "constant_velocity"}}],
            "horizons": [1], "flow": "dis", "track": {"tracker": {"confirm": 2}}}"#,
    )
    .unwrap();
    let out = d.path().join("out");
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_pins"))
        .args(["track", "experiment", "--config"])
        .arg(&cfg)
        .arg("--out")
        .arg(&out)
        .arg("--no-plots")
        .output()
        .unwrap();
    let text =
        String::from_utf8_lossy(&run.stdout).to_string() + &String::from_utf8_lossy(&run.stderr);
    if !run.status.success() {
        assert!(text.contains("dis"), "{text}");
        eprintln!("DIS experiment not checked (no OpenCV for python3?): {text}");
        return;
    }
    assert!(text.contains("DIS flow:"), "{text}");
    let r = json(&out.join("report.json"));
    assert_eq!(r["flow"], "dis");
    assert!(r["flow_ms_per_frame"].as_f64().unwrap() > 0.0);
    // The disc is found: the pooled one-frame row has samples and a finite error.
    let rows = r["rows"].as_array().unwrap();
    let pooled = rows
        .iter()
        .find(|row| row["object"].is_null() && row["horizon"] == 1)
        .expect("pooled row");
    assert!(pooled["count"].as_u64().unwrap() > 0, "{text}");
    assert!(pooled["rmse_2d"].as_f64().unwrap() < 10.0, "{text}");
}
