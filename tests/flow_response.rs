//! `scripts/flow_response.py` (the ledger's diagnosis of small motions): on flows whose answer
//! is known, it reports the share of each motion an estimate gives, per band of true length, and
//! the slope of each component; bad files are refused with the reason. Runs where Python has
//! numpy (`PINS_PYTHON`, else `python3`); says SKIPPED otherwise.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

fn python() -> Option<String> {
    common::python("flow_response", "numpy")
}

fn script() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/flow_response.py")
}

/// A flow of `h × w` whose u grows along each row from 0.1 to `max` px, v half of it, times
/// `gain`.
fn ramp(h: usize, w: usize, max: f32, gain: f32) -> pins::Flow {
    let u: Vec<f32> = (0..h * w)
        .map(|i| gain * (0.1 + (max - 0.1) * (i % w) as f32 / (w - 1) as f32))
        .collect();
    let v: Vec<f32> = u.iter().map(|x| 0.5 * x).collect();
    pins::Flow::from_vec(h, w, [u, v].concat()).unwrap()
}

#[test]
fn reports_the_share_of_each_motion_the_estimate_gives() {
    let Some(py) = python() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let (truth, half, whole) = (
        tmp.path().join("truth.flo"),
        tmp.path().join("half.flo"),
        tmp.path().join("whole.flo"),
    );
    pins::io::flo::write_flo(&truth, &ramp(8, 200, 12.0, 1.0)).unwrap();
    pins::io::flo::write_flo(&half, &ramp(8, 200, 12.0, 0.5)).unwrap();
    pins::io::flo::write_flo(&whole, &ramp(8, 200, 12.0, 1.0)).unwrap();
    let run = |est: &Path| {
        let spec = format!("{}:{}", est.display(), truth.display());
        let out = Command::new(&py).arg(script()).arg(spec).output().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    // Half of every motion: 0.50 in every band, slopes 0.50.
    let text = run(&half);
    let bands: Vec<&str> = text
        .lines()
        .filter(|l| l.starts_with("| ") && l.contains(" px |") && !l.contains("true motion"))
        .collect();
    assert!(bands.len() >= 4, "{text}");
    for line in &bands {
        assert!(line.trim_end().ends_with("| 0.50 |"), "{line}\n{text}");
    }
    // Half of a motion is within 1 px of it below 2 px and never from 2 px on; the median
    // error is half the band's motion.
    let cells = |band: &str| -> Vec<String> {
        let line = bands.iter().find(|l| l.starts_with(&format!("| {band} |")));
        let line = line.unwrap_or_else(|| panic!("no band {band}\n{text}"));
        line.split('|').map(|c| c.trim().to_string()).collect()
    };
    assert_eq!(cells("1–2 px")[4], "1.000", "{text}");
    assert_eq!(cells("4–8 px")[4], "0.000", "{text}");
    let median: f64 = cells("4–8 px")[5].parse().unwrap();
    assert!((2.0..4.0).contains(&median), "{text}");
    assert!(
        text.contains("u: slope 0.50") && text.contains("v: slope 0.50"),
        "{text}"
    );
    // The whole motion: 1.00 and an EPE of zero.
    let text = run(&whole);
    assert!(
        text.contains("EPE 0.000") && text.contains("u: slope 1.00"),
        "{text}"
    );

    // A file that is not a flow, and sizes that differ, are refused with the reason.
    let bad = tmp.path().join("bad.flo");
    std::fs::write(&bad, b"not a flow at all").unwrap();
    let small = tmp.path().join("small.flo");
    pins::io::flo::write_flo(&small, &ramp(4, 20, 3.0, 1.0)).unwrap();
    for (est, want) in [(&bad, "not a .flo file"), (&small, "20x4")] {
        let spec = format!("{}:{}", est.display(), truth.display());
        let out = Command::new(&py).arg(script()).arg(spec).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(want), "{err}");
    }
}
