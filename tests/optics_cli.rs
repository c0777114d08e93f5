//! `pins optics` and `pins compare` from the command line: Table S1 as JSON, stereo errors,
//! image similarity.

mod common;
use common::pins;

#[test]
fn dof_json_reproduces_table_s1() {
    let out = pins(&["optics", "dof", "--json"]);
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let rows = v["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 5);
    assert!(rows[0]["u_far_m"].is_null(), "infinity is null");
    assert!((rows[1]["u_near_m"].as_f64().unwrap() - 0.15).abs() < 0.005);
    assert!((rows[1]["u_far_m"].as_f64().unwrap() - 0.87).abs() < 0.005);
}

#[test]
fn stereo_rejects_rays_that_do_not_meet() {
    let out = pins(&[
        "optics",
        "stereo",
        "--x1-mm",
        "0.1",
        "--x2-mm",
        "0.1",
        "--baseline-m",
        "0.1",
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("do not meet"));
    let out = pins(&[
        "optics",
        "stereo",
        "--x1-mm",
        "-2",
        "--x2-mm",
        "-0.1",
        "--baseline-m",
        "0.1",
        "--profile",
        "quadratic",
    ]);
    assert!(!out.status.success());
}

#[test]
fn compare_prints_ssim_mae_mse() {
    let d = tempfile::tempdir().unwrap();
    let (a, b) = (d.path().join("a.png"), d.path().join("b.png"));
    let mut img = pins::Image::filled(3, 32, 32, 0.5);
    pins::io::write_image(&a, &img, pins::io::BitDepth::Eight).unwrap();
    img.set(1, 10, 10, 0.9);
    pins::io::write_image(&b, &img, pins::io::BitDepth::Eight).unwrap();
    let out = pins(&[
        "compare",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(
        v["ssim"].as_f64().unwrap() < 1.0
            && v["mae"].as_f64().unwrap() > 0.0
            && v["mse"].as_f64().unwrap() > 0.0
    );
    let c = d.path().join("c.png");
    pins::io::write_image(
        &c,
        &pins::Image::filled(3, 30, 32, 0.5),
        pins::io::BitDepth::Eight,
    )
    .unwrap();
    assert!(
        !pins(&["compare", a.to_str().unwrap(), c.to_str().unwrap()])
            .status
            .success()
    );
}
