//! `scripts/shift_pairs.py` and `scripts/motion_stages.py` (the ledger's diagnosis of the
//! network's dead zone): exact sub-pixel translations of a photograph carry their flow, and
//! along the shipped network the features and the first correlation window follow the motion.
//! Runs where Python has numpy, Pillow and torch (`PINS_PYTHON`, else `python3`); says SKIPPED
//! otherwise.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

fn python() -> Option<String> {
    common::python("motion_stages", "numpy, PIL, torch")
}

fn repo(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

fn run(py: &str, args: &[&str]) -> std::process::Output {
    Command::new(py).args(args).output().unwrap()
}

#[test]
fn translations_carry_their_flow_and_the_network_stages_follow_them() {
    let Some(py) = python() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let data = tmp.path().join("shifts");
    let data_s = data.to_str().unwrap();
    let shift = repo("scripts/shift_pairs.py");
    let photo = repo("datasets/photos/bench/chelsea.png");
    let out = run(
        &py,
        &[
            shift.to_str().unwrap(),
            photo.to_str().unwrap(),
            "--out",
            data_s,
            "--shifts",
            "0.25,0.5,1,2",
            "--angle",
            "0",
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    // Frame 2 is frame 1 moved by the flow: sampled back along the flow (bilinear), it matches
    // frame 1 better than frame 2 unmoved does (bilinear sampling and 8 bits keep it from 0).
    let read = |i: usize, name: &str| {
        pins::io::read_image(&data.join(format!("{i:05}_{name}.png"))).unwrap()
    };
    for (i, d) in [0.25f32, 0.5, 1.0, 2.0].into_iter().enumerate() {
        let (a, b) = (read(i, "img1"), read(i, "img2"));
        let flow = pins::io::read_flo(&data.join(format!("{i:05}_flow.flo"))).unwrap();
        assert_eq!((flow.height(), flow.width()), (a.height(), a.width()));
        assert!(
            flow.data()[..flow.height() * flow.width()]
                .iter()
                .all(|&u| u == d)
        );
        let (h, w) = (a.height(), a.width());
        let (mut moved, mut still, mut n) = (0.0f64, 0.0f64, 0usize);
        for y in 4..h - 4 {
            for x in 4..w - 4 {
                let xs = x as f32 + d; // frame 2 at x + d holds frame 1 at x
                let (x0, t) = (xs.floor() as usize, xs - xs.floor());
                for c in 0..3 {
                    let p = b.plane(c);
                    let s = (1.0 - t) * p[y * w + x0] + t * p[y * w + x0 + 1];
                    let a1 = a.plane(c)[y * w + x];
                    moved += ((s - a1) as f64).abs();
                    still += ((p[y * w + x] - a1) as f64).abs();
                }
                n += 1;
            }
        }
        let (moved, still) = (moved / n as f64, still / n as f64);
        assert!(
            moved < 0.7 * still,
            "shift {d}: {moved:.5} moved, {still:.5} unmoved"
        );
    }

    let script = repo("scripts/motion_stages.py");
    let stages = |weights: &Path, data: &Path| {
        let args = [
            script.as_path(),
            Path::new("--weights"),
            weights,
            Path::new("--data"),
            data,
        ];
        run(&py, &args.map(|a| a.to_str().unwrap()))
    };
    let weights = repo("datasets/weights/mms-small-real.safetensors");
    let out = stages(&weights, &data);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    // | (u, v) | feature change | correlation peak | first update |
    let rows: Vec<[f64; 3]> = text
        .lines()
        .filter(|l| l.starts_with("| (+"))
        .map(|l| {
            let cells: Vec<&str> = l.split('|').map(str::trim).collect();
            [
                cells[2].parse().unwrap(),
                cells[3].parse().unwrap(),
                cells[4].parse().unwrap(),
            ]
        })
        .collect();
    assert_eq!(rows.len(), 4, "{text}");
    for pair in rows.windows(2) {
        let (s, l) = (pair[0], pair[1]);
        assert!(l[0] > 1.5 * s[0], "feature change does not grow: {text}");
        assert!(
            l[1] > s[1] && s[1] > 0.0,
            "correlation peak does not follow: {text}"
        );
    }
    // Beyond the dead zone the first update moves the flow most of the way.
    assert!(rows[3][2] > 1.0, "{text}");

    // A folder without flows, and weights that are not weights, are refused with the reason.
    let empty = tmp.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let out = stages(&weights, &empty);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("no *_flow.flo"));
    let out = stages(&photo, &data);
    assert!(!out.status.success());
    assert!(!String::from_utf8_lossy(&out.stderr).contains("Traceback"));
}
