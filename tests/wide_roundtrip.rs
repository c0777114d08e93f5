//! The wide-angle array end to end (Note S3): render a known 135° scene and the dot grid
//! through the three tilted lenses, calibrate from the grid, stitch, and compare.

use pins::imaging::similarity::compare;
use pins::wide::render::{dot_grid_target, render_raw};
use pins::wide::{ArrayLayout, Stitcher, calibrate};

#[test]
fn render_calibrate_stitch_round_trip() {
    let layout = ArrayLayout::default();
    pins::wide::render::check_layout(&layout).unwrap();
    let (grid, _) = dot_grid_target(&layout, 11).unwrap();
    let raw_grid = render_raw(&layout, &grid).unwrap();
    assert_eq!((raw_grid.height(), raw_grid.width()), (1200, 1600));
    let calib = calibrate(&layout, &raw_grid, 11, None).unwrap();
    for (i, l) in calib.lenses.iter().enumerate() {
        assert_eq!(l.dots, 121, "lens {i}");
        assert!(
            l.rms_px < 0.15 && l.max_px < 0.5,
            "lens {i}: rms {} max {} (order {})",
            l.rms_px,
            l.max_px,
            l.fx.order
        );
    }
    let scene = pins::scene::texture::procedural(5, 3, 480, 1440, 160.0);
    let raw = render_raw(&layout, &scene).unwrap();
    let wide = Stitcher::new(&calib).unwrap().apply(&raw).unwrap();
    assert_eq!((wide.height(), wide.width()), (480, 1440));
    let s = compare(&scene, &wide).unwrap();
    assert!(s.ssim > 0.9 && s.mae < 0.02 && s.mse < 0.002, "{s:?}");
}

#[test]
fn bad_frames_are_rejected() {
    let layout = ArrayLayout::default();
    // A frame of another size.
    let wrong = pins::Image::zeros(1, 600, 800);
    assert!(calibrate(&layout, &wrong, 11, None).is_err());
    // A frame without dots: the message says how many were found and expected.
    let blank = pins::Image::filled(1, 1200, 1600, 0.7);
    let err = calibrate(&layout, &blank, 11, None)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("found 0 dots") && err.contains("121 expected"),
        "{err}"
    );
    // Too few dots for the polynomial order.
    let (grid, _) = dot_grid_target(&layout, 3).unwrap();
    let raw = render_raw(&layout, &grid).unwrap();
    assert!(calibrate(&layout, &raw, 3, Some(6)).is_err());
}
