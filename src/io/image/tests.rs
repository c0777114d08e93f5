//! The raster readers' and writers' tests: every format both ways, bit depths, bad files.

use super::*;

fn ramp(c: usize, h: usize, w: usize) -> Image {
    let n = c * h * w;
    let data = (0..n).map(|i| i as f32 / (n - 1) as f32).collect();
    Image::from_vec(c, h, w, data).unwrap()
}

fn close(a: &Image, b: &Image, tol: f32) {
    assert_eq!(a.shape(), b.shape());
    for (x, y) in a.data().iter().zip(b.data()) {
        assert!((x - y).abs() <= tol, "{x} vs {y}");
    }
}

#[test]
fn png_tiff_pnm_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    for ext in ["png", "tif", "ppm", "pgm"] {
        for (depth, tol) in [
            (BitDepth::Eight, 0.5 / 255.0),
            (BitDepth::Sixteen, 0.5 / 65535.0),
        ] {
            for c in [1, 3] {
                if ext == "pgm" && c == 3 {
                    continue;
                }
                let im = ramp(c, 5, 7);
                let p = dir.path().join(format!("a{c}{depth:?}.{ext}"));
                write_image(&p, &im, depth).unwrap();
                let back = read_image(&p).unwrap();
                if ext == "ppm" && c == 1 {
                    assert_eq!(back.channels(), 3);
                    assert!(back.is_grey());
                    close(&back.first_channel(), &im, tol * 1.01);
                } else {
                    close(&back, &im, tol * 1.01);
                }
            }
        }
    }
}

#[test]
fn png_exact_quantisation_and_rgba() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("q.png");
    let im = Image::from_vec(1, 1, 4, vec![-0.5, 0.5, 1.0, 2.0]).unwrap();
    write_image(&p, &im, BitDepth::Eight).unwrap();
    assert_eq!(
        read_image(&p).unwrap().data(),
        &[0.0, 128.0 / 255.0, 1.0, 1.0]
    );
    let rgba = ramp(4, 3, 3);
    write_image(&p, &rgba, BitDepth::Sixteen).unwrap();
    let back = read_image(&p).unwrap();
    assert_eq!(back.channels(), 3, "alpha is dropped on read");
    close(
        &back,
        &Image::from_vec(3, 3, 3, rgba.data()[..27].to_vec()).unwrap(),
        1e-5,
    );
}

#[test]
fn jpeg_is_close() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("a.jpg");
    let im = Image::filled(3, 16, 16, 0.5);
    write_image(&p, &im, BitDepth::Eight).unwrap();
    close(&read_image(&p).unwrap(), &im, 3.0 / 255.0);
    assert!(write_image(&p.with_extension("jpeg"), &im, BitDepth::Sixteen).is_err());
}

#[test]
fn write_errors() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("e.png");
    let e = write_image(&p, &ramp(2, 2, 2), BitDepth::Eight)
        .unwrap_err()
        .to_string();
    assert!(e.contains("has 2"), "{e}");
    assert!(write_image(&p, &ramp(5, 2, 2), BitDepth::Eight).is_err());
    let mut im = ramp(3, 2, 2);
    im.set(1, 1, 0, f32::INFINITY);
    let e = write_image(&p, &im, BitDepth::Eight)
        .unwrap_err()
        .to_string();
    assert!(e.contains("channel 1, row 1, column 0"), "{e}");
    let e = write_image(&dir.path().join("x.bmp"), &ramp(1, 2, 2), BitDepth::Eight)
        .unwrap_err()
        .to_string();
    assert!(e.contains("png"), "{e}");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

#[test]
fn corrupt_file_is_format_error() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("c.png");
    write_image(&p, &ramp(3, 8, 8), BitDepth::Eight).unwrap();
    let mut bytes = std::fs::read(&p).unwrap();
    bytes.truncate(bytes.len() / 2);
    std::fs::write(&p, &bytes).unwrap();
    let e = read_image(&p).unwrap_err();
    assert!(matches!(e, Error::Format { .. }), "{e}");
    assert!(e.to_string().contains("c.png"), "{e}");
    std::fs::write(&p, b"hello, not an image").unwrap();
    assert!(matches!(read_image(&p).unwrap_err(), Error::Format { .. }));
    let missing = read_image(&dir.path().join("none.png")).unwrap_err();
    assert!(matches!(missing, Error::Io { .. }));
}

#[test]
fn pair_size_mismatch_names_both() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a.png"), dir.path().join("b.png"));
    write_image(&a, &ramp(1, 4, 4), BitDepth::Eight).unwrap();
    write_image(&b, &ramp(1, 4, 5), BitDepth::Eight).unwrap();
    let e = read_image_pair(&a, &b).unwrap_err().to_string();
    assert!(e.contains("a.png") && e.contains("b.png"), "{e}");
    assert!(read_image_pair(&a, &a).is_ok());
}

#[test]
fn empty_and_over_budget_rasters_are_refused_before_decoding() {
    // Fuzzing find: a PGM declaring width 0 decoded to an image with no pixels.
    let e = decode_image(b"P5\n0 1\n255\n", Path::new("z.pgm"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("z.pgm") && e.contains("empty"), "{e}");
    // 16000x16000 declared by a 20-byte file: refused from the header.
    let e = decode_image(b"P5\n16000 16000\n255\n\0\0", Path::new("big.pgm"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("big.pgm") && e.contains("16000x16000") && e.contains("--max-pixels"),
        "{e}"
    );
}

#[test]
fn float_images_need_one_or_three_channels() {
    use crate::io::{write_exr, write_flow_exr};
    use crate::types::Flow;
    let dir = tempfile::tempdir().unwrap();
    // A flow EXR (u, v) given as an image: the message is about images, not PSFs.
    let p = dir.path().join("flow.exr");
    write_flow_exr(&p, &Flow::zeros(3, 4)).unwrap();
    let e = read_image(&p).unwrap_err().to_string();
    assert!(
        e.contains("flow.exr")
            && e.contains("an image needs 1 channel")
            && e.contains("[u, v]")
            && e.contains("flow field"),
        "{e}"
    );
    let p = dir.path().join("four.exr");
    write_exr(&p, &ramp(4, 2, 3)).unwrap();
    let e = read_image(&p).unwrap_err().to_string();
    assert!(e.contains("[C0, C1, C2, C3]"), "{e}");
    // .npy: two channels are refused, a fourth (alpha) is dropped.
    let p = dir.path().join("two.npy");
    write_npy(&p, &ramp(2, 2, 5)).unwrap();
    let e = read_image(&p).unwrap_err().to_string();
    assert!(e.contains("two.npy") && e.contains("2 channels"), "{e}");
    let p = dir.path().join("rgba.npy");
    let im = ramp(4, 2, 5);
    write_npy(&p, &im).unwrap();
    let back = read_image(&p).unwrap();
    assert_eq!(back.shape(), (3, 2, 5));
    assert_eq!(back.data(), &im.data()[..30]);
}
