//! `pins track` on a folder of flows: IDs, predictions at the horizons, and bad input.

use std::process::Command;

use pins::Flow;

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
}
