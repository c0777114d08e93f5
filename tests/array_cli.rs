//! `pins array` end to end: render, calibrate, stitch, and the bad inputs of Note S3's pipeline.

mod common;
use common::{failed as err, ok, pins};

#[test]
fn render_calibrate_stitch_and_bad_input() {
    let d = tempfile::tempdir().unwrap();
    let p = |n: &str| d.path().join(n).to_string_lossy().into_owned();
    ok(&pins(&[
        "array",
        "render",
        "--grid",
        "--out",
        &p("grid.png"),
        "--seed",
        "2",
    ]));
    let table = ok(&pins(&[
        "array",
        "calibrate",
        "--grid",
        &p("grid.png"),
        "--out",
        &p("calib.json"),
    ]));
    assert!(
        table.contains("| 1 |") && table.contains("| 3 |"),
        "{table}"
    );
    let wide = pins::scene::texture::procedural(9, 3, 480, 1440, 150.0);
    pins::io::write_image(
        std::path::Path::new(&p("wide.png")),
        &wide,
        pins::io::BitDepth::Eight,
    )
    .unwrap();
    ok(&pins(&[
        "array",
        "render",
        "--in",
        &p("wide.png"),
        "--out",
        &p("raw.png"),
        "--camera",
        "none",
    ]));
    ok(&pins(&[
        "array",
        "stitch",
        "--calib",
        &p("calib.json"),
        "--in",
        &p("raw.png"),
        "--out",
        &p("stitched.png"),
    ]));
    let back = pins::io::read_image(std::path::Path::new(&p("stitched.png"))).unwrap();
    assert_eq!((back.width(), back.height()), (1440, 480));
    let s = pins::imaging::similarity::compare(
        &pins::io::read_image(std::path::Path::new(&p("wide.png"))).unwrap(),
        &back,
    )
    .unwrap();
    assert!(s.ssim > 0.85, "{s:?}");

    // A frame without a grid: how many dots were found and expected.
    ok(&pins(&[
        "array",
        "render",
        "--in",
        &p("wide.png"),
        "--out",
        &p("not_grid.png"),
        "--camera",
        "none",
    ]));
    let e = err(&pins(&[
        "array",
        "calibrate",
        "--grid",
        &p("not_grid.png"),
        "--out",
        &p("bad.json"),
    ]));
    assert!(e.contains("expected"), "{e}");
    assert!(!d.path().join("bad.json").exists());
    // A raw frame of the wrong size.
    pins::io::write_image(
        std::path::Path::new(&p("small.png")),
        &pins::Image::zeros(3, 600, 800),
        pins::io::BitDepth::Eight,
    )
    .unwrap();
    let e = err(&pins(&[
        "array",
        "stitch",
        "--calib",
        &p("calib.json"),
        "--in",
        &p("small.png"),
        "--out",
        &p("never.png"),
    ]));
    assert!(e.contains("800x600"), "{e}");
    assert!(!d.path().join("never.png").exists());
    // A calibration made for another sensor.
    let text = std::fs::read_to_string(p("calib.json"))
        .unwrap()
        .replacen("1600", "1400", 1);
    std::fs::write(p("other.json"), text).unwrap();
    let e = err(&pins(&[
        "array",
        "stitch",
        "--calib",
        &p("other.json"),
        "--in",
        &p("raw.png"),
        "--out",
        &p("never.png"),
    ]));
    assert!(e.contains("raw frame") || e.contains("layout"), "{e}");
    // A degenerate fit and a bad order.
    let e = err(&pins(&[
        "array",
        "calibrate",
        "--grid",
        &p("grid.png"),
        "--out",
        &p("bad.json"),
        "--order",
        "9",
    ]));
    assert!(e.contains("--order"), "{e}");
    // A wide scene of the wrong size.
    let e = err(&pins(&[
        "array",
        "render",
        "--in",
        &p("small.png"),
        "--out",
        &p("never.png"),
    ]));
    assert!(e.contains("1440x480"), "{e}");
}
