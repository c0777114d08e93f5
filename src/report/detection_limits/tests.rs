//! Note S12's detection-limit report's tests: the cases, their scores, the figure and the table.

use super::*;

fn disc_truth() -> Flow {
    let (h, w) = (40, 40);
    let mut f = Flow::zeros(h, w);
    let (u, v) = f.planes_mut();
    for y in 15..25 {
        for x in 15..25 {
            u[y * w + x] = 6.0;
            v[y * w + x] = 0.0;
        }
    }
    f
}

#[test]
fn exact_flow_is_detected_with_no_error_and_no_false_motion() {
    let cfg = LimitsConfig::default();
    let t = disc_truth();
    let s = score(&cfg, "x", 1, &t, &t, 0.0);
    assert_eq!(s.region_px, 100);
    assert!(s.direction_error_deg < 1e-6 && s.magnitude_error.abs() < 1e-9);
    assert_eq!(s.detected_fraction, 1.0);
    assert_eq!(s.false_motion_px, 0);
    assert!(s.detected);
}

#[test]
fn wrong_direction_zero_flow_and_false_motion_are_caught() {
    let cfg = LimitsConfig::default();
    let t = disc_truth();
    // The estimate points up: 90° off.
    let mut up = Flow::zeros(40, 40);
    {
        let (_, v) = up.planes_mut();
        for y in 15..25 {
            for x in 15..25 {
                v[y * 40 + x] = -6.0;
            }
        }
        // A false blob far from the disc.
        for y in 0..3 {
            for x in 0..3 {
                v[y * 40 + x] = 2.0;
            }
        }
    }
    let s = score(&cfg, "x", 1, &t, &up, 0.0);
    assert!((s.direction_error_deg - 90.0).abs() < 1e-6);
    assert!(!s.detected);
    assert_eq!(s.false_motion_px, 9);
    let z = score(&cfg, "x", 1, &t, &Flow::zeros(40, 40), 0.0);
    assert_eq!(z.detected_fraction, 0.0);
    assert!(!z.detected);
}

#[test]
fn bad_configs_are_rejected() {
    for bad in [
        r#"{"cases": []}"#,
        r#"{"cases": [{"disc": -3}]}"#,
        r#"{"iters": [0]}"#,
        r#"{"moving_px": -1}"#,
        r#"{"min_detected": 2}"#,
        r#"{"frames": []}"#,
        r#"{"frames": [150]}"#,
        r#"{"frames": [701, 5000]}"#,
        r#"{"cases": [{"disc": 120}], "frames": [701, 240]}"#,
    ] {
        let cfg: LimitsConfig = serde_json::from_str(bad).unwrap();
        assert!(cfg.validate().is_err(), "{bad}");
    }
    assert!(serde_json::from_str::<LimitsConfig>(r#"{"case": []}"#).is_err());
    let ok: LimitsConfig =
        serde_json::from_str(r#"{"cases": [{"rocket": "up_right"}, {"disc": 5}]}"#).unwrap();
    assert!(ok.validate().is_ok());
    assert_eq!(ok.cases[0].name(), "rocket up_right");
    assert_eq!(ok.cases[0].name_in(701), "rocket up_right");
    assert_eq!(ok.cases[1].name_in(1024), "disc r = 5 in 1024×1024");
    let sweep: LimitsConfig =
        serde_json::from_str(r#"{"cases": [{"disc": 100}], "frames": [256, 701]}"#).unwrap();
    assert!(sweep.validate().is_ok());
}
