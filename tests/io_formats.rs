//! Integration tests of `pins::io` on files written by other tools (`../shared/data`, see its
//! SOURCES.md): .flo, KITTI PNG flow, PFM, PPM/PNG frames and 16-bit TIFF; the pixel budget
//! and reader messages through `pins simulate`.

mod common;

use std::path::{Path, PathBuf};

use pins::io::{
    encode_flo, read_flo, read_flow, read_image, read_image_pair, read_kitti_flow, read_pfm,
};
use pins::{Flow, Image};

/// `../shared/data`, or `None` (with a note on stderr) when it is not there.
fn data_dir() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
    if dir.is_dir() {
        Some(dir)
    } else {
        eprintln!(
            "skipping: ../shared/data not found (looked for {})",
            dir.display()
        );
        None
    }
}

/// Every .flo in the data set: (file, width, height, max magnitude, valid fraction), from
/// SOURCES.md.
const FLO: &[(&str, usize, usize, f32, f64)] = &[
    ("flyingchairs/0000001-gt.flo", 512, 384, 63.54, 1.0),
    ("flyingchairs/0000004-gt.flo", 512, 384, 59.98, 1.0),
    ("flyingchairs/0000005-gt.flo", 512, 384, 102.06, 1.0),
    ("flyingchairs_crops/0000000-flow_01.flo", 50, 50, 23.52, 1.0),
    ("flyingchairs_crops/0000000-flow_10.flo", 50, 50, 0.49, 1.0),
    ("flyingchairs_crops/00001_flow.flo", 50, 50, 12.51, 1.0),
    ("middlebury_rubberwhale/flow10.flo", 584, 388, 4.62, 0.984),
    ("sintel_alley1/frame_0001.flo", 1024, 436, 8.42, 1.0),
];

/// (flow, frame 1, frame 2, reported warped error, reported unwarped error; 0-255 scale).
const PAIRS: &[(&str, &str, &str, f64, f64)] = &[
    (
        "flyingchairs/0000001-gt.flo",
        "flyingchairs/0000001-img0.ppm",
        "flyingchairs/0000001-img1.ppm",
        5.83,
        17.15,
    ),
    (
        "flyingchairs/0000004-gt.flo",
        "flyingchairs/0000004-img0.ppm",
        "flyingchairs/0000004-img1.ppm",
        7.60,
        53.00,
    ),
    (
        "flyingchairs/0000005-gt.flo",
        "flyingchairs/0000005-img0.ppm",
        "flyingchairs/0000005-img1.ppm",
        9.83,
        42.46,
    ),
    (
        "flyingchairs_crops/0000000-flow_01.flo",
        "flyingchairs_crops/0000000-img_0.png",
        "flyingchairs_crops/0000000-img_1.png",
        9.80,
        10.06,
    ),
    (
        "flyingchairs_crops/0000000-flow_10.flo",
        "flyingchairs_crops/0000000-img_1.png",
        "flyingchairs_crops/0000000-img_0.png",
        9.63,
        10.22,
    ),
    (
        "flyingchairs_crops/00001_flow.flo",
        "flyingchairs_crops/00001_img1.ppm",
        "flyingchairs_crops/00001_img2.ppm",
        2.22,
        4.54,
    ),
    (
        "middlebury_rubberwhale/flow10.flo",
        "middlebury_rubberwhale/frame10.png",
        "middlebury_rubberwhale/frame11.png",
        1.28,
        5.58,
    ),
    (
        "sintel_alley1/frame_0001.flo",
        "sintel_alley1/frame_0001.png",
        "sintel_alley1/frame_0002.png",
        2.63,
        10.11,
    ),
    (
        "kitti2015_000000/flow_gt.png",
        "kitti2015_000000/frame1.png",
        "kitti2015_000000/frame2.png",
        f64::NAN,
        f64::NAN,
    ),
];

fn valid_fraction(f: &Flow) -> f64 {
    let m = f.valid_mask();
    m.iter().filter(|&&v| v).count() as f64 / m.len() as f64
}

/// Bilinear sample of channel `c` at (x, y), which must lie inside the image.
fn bilinear(im: &Image, c: usize, x: f32, y: f32) -> f32 {
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(im.width() - 1), (y0 + 1).min(im.height() - 1));
    let (fx, fy) = (x - x0 as f32, y - y0 as f32);
    let top = im.get(c, y0, x0) * (1.0 - fx) + im.get(c, y0, x1) * fx;
    let bottom = im.get(c, y1, x0) * (1.0 - fx) + im.get(c, y1, x1) * fx;
    top * (1.0 - fy) + bottom * fy
}

/// Mean |I2(x + f) - I1(x)| and mean |I2(x) - I1(x)| over pixels with a valid flow landing
/// inside the image, on the 0-255 scale, averaged over channels.
fn warp_errors(f: &Flow, i1: &Image, i2: &Image) -> (f64, f64) {
    let (h, w) = (f.height(), f.width());
    let (mut warped, mut plain, mut n) = (0.0f64, 0.0f64, 0usize);
    for y in 0..h {
        for x in 0..w {
            let (u, v) = f.get(y, x);
            let (xs, ys) = (x as f32 + u, y as f32 + v);
            if !(u.is_finite() && v.is_finite())
                || xs < 0.0
                || ys < 0.0
                || xs > (w - 1) as f32
                || ys > (h - 1) as f32
            {
                continue;
            }
            for c in 0..i1.channels() {
                let a = i1.get(c, y, x);
                warped += f64::from((bilinear(i2, c, xs, ys) - a).abs());
                plain += f64::from((i2.get(c, y, x) - a).abs());
            }
            n += i1.channels();
        }
    }
    assert!(n > 0, "no pixel lands inside the image");
    (255.0 * warped / n as f64, 255.0 * plain / n as f64)
}

#[test]
fn every_flo_parses_with_documented_size_and_magnitude() {
    let Some(dir) = data_dir() else { return };
    let mut seen = 0;
    for sub in [
        "flyingchairs",
        "flyingchairs_crops",
        "middlebury_rubberwhale",
        "sintel_alley1",
    ] {
        let mut entries: Vec<PathBuf> = std::fs::read_dir(dir.join(sub))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "flo"))
            .collect();
        entries.sort();
        for p in entries {
            let rel = format!("{sub}/{}", p.file_name().unwrap().to_string_lossy());
            let f = read_flo(&p).unwrap_or_else(|e| panic!("{e}"));
            let &(_, w, h, max, valid) = FLO
                .iter()
                .find(|r| r.0 == rel)
                .unwrap_or_else(|| panic!("{rel} is not listed in the test table"));
            assert_eq!((f.width(), f.height()), (w, h), "{rel}");
            assert!(
                (f.max_magnitude() - max).abs() < 0.01,
                "{rel}: max {}",
                f.max_magnitude()
            );
            let vf = valid_fraction(&f);
            assert!((vf - valid).abs() < 0.001, "{rel}: valid fraction {vf}");
            // Same field through the dispatcher; byte-exact re-encoding when nothing is unknown.
            assert_eq!(read_flow(&p).unwrap().valid_mask(), f.valid_mask());
            if valid == 1.0 {
                assert_eq!(
                    encode_flo(&f),
                    std::fs::read(&p).unwrap(),
                    "{rel}: re-encoding"
                );
            }
            seen += 1;
        }
    }
    assert_eq!(seen, FLO.len());
    let mb = read_flo(&dir.join("middlebury_rubberwhale/flow10.flo")).unwrap();
    let unknown = 1.0 - valid_fraction(&mb);
    assert!(
        (0.012..0.02).contains(&unknown),
        "middlebury unknown fraction {unknown}"
    );
    assert!(mb.u().iter().any(|v| v.is_nan()));
}

#[test]
fn pairs_load_and_flow_explains_motion() {
    let Some(dir) = data_dir() else { return };
    for &(flow, a, b, rep_warped, rep_plain) in PAIRS {
        let f = read_flow(&dir.join(flow)).unwrap_or_else(|e| panic!("{e}"));
        let (i1, i2) = read_image_pair(&dir.join(a), &dir.join(b)).unwrap();
        assert_eq!(
            (i1.height(), i1.width()),
            (f.height(), f.width()),
            "{a} vs {flow}"
        );
        assert_eq!(i1.channels(), 3, "{a}");
        let (warped, plain) = warp_errors(&f, &i1, &i2);
        eprintln!(
            "{flow}: warp error {warped:.2} vs {plain:.2} without flow (SOURCES.md: \
             {rep_warped:.2} vs {rep_plain:.2})"
        );
        assert!(
            warped < plain,
            "{flow}: warping by the flow does not help ({warped} vs {plain})"
        );
        // Swapping u and v, or flipping their sign, must do worse: this pins down the order
        // and the sign convention of the readers.
        if plain > 4.0 && !flow.contains("0000000-flow") {
            let (h, w) = (f.height(), f.width());
            let swapped = Flow::from_vec(h, w, [f.v(), f.u()].concat()).unwrap();
            let negated = Flow::from_vec(h, w, f.data().iter().map(|x| -x).collect()).unwrap();
            for (name, g) in [("swapped", swapped), ("negated", negated)] {
                let (bad, _) = warp_errors(&g, &i1, &i2);
                assert!(
                    bad > warped,
                    "{flow}: {name} flow warps better ({bad} vs {warped})"
                );
            }
        }
        // Where the sets have real motion, the flow must explain most of the difference.
        if plain > 4.0 && !flow.contains("0000000-flow") {
            assert!(warped < 0.7 * plain, "{flow}: {warped} vs {plain}");
        }
    }
}

#[test]
fn kitti_flow_png() {
    let Some(dir) = data_dir() else { return };
    let p = dir.join("kitti2015_000000/flow_gt.png");
    let (f, valid) = read_kitti_flow(&p).unwrap();
    assert_eq!((f.width(), f.height()), (1242, 375));
    assert_eq!(valid, f.valid_mask());
    let vf = valid_fraction(&f);
    assert!((vf - 0.162).abs() < 0.002, "valid fraction {vf}");
    assert!(
        (f.max_magnitude() - 189.95).abs() < 0.05,
        "max {}",
        f.max_magnitude()
    );
    let umin = f
        .u()
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(f32::INFINITY, f32::min);
    assert!((umin + 184.25).abs() < 0.02, "u min {umin}");
    // An 8-bit RGB frame is not a flow file.
    let e = read_kitti_flow(&dir.join("kitti2015_000000/frame1.png"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("16-bit"), "{e}");
}

#[test]
fn pfm_occlusion_weights() {
    let Some(dir) = data_dir() else { return };
    for name in ["0000000-occ_weights_01.pfm", "0000000-occ_weights_10.pfm"] {
        let im = read_pfm(&dir.join("flyingchairs_crops").join(name)).unwrap();
        assert_eq!(im.shape(), (1, 50, 50), "{name}");
        assert!(im.data().iter().all(|v| (0.0..=1.0).contains(v)), "{name}");
        assert_eq!(
            read_image(&dir.join("flyingchairs_crops").join(name)).unwrap(),
            im
        );
    }
}

#[test]
fn sixteen_bit_tiff_psf() {
    let Some(dir) = data_dir() else { return };
    let psf = read_image(&dir.join("psf_diffusercam/psf_sample.tif")).unwrap();
    assert_eq!(psf.shape(), (1, 1200, 1600));
    let max = psf.data().iter().copied().fold(0.0f32, f32::max);
    assert!(
        (max * 65535.0 - 65520.0).abs() < 0.5,
        "max {}",
        max * 65535.0
    );
    let raw = read_image(&dir.join("psf_diffusercam/rawdata_hand_sample.tif")).unwrap();
    let (lo, hi) = raw
        .data()
        .iter()
        .fold((f32::INFINITY, 0.0f32), |(l, h), &v| (l.min(v), h.max(v)));
    assert_eq!(
        ((lo * 65535.0).round(), (hi * 65535.0).round()),
        (144.0, 37184.0)
    );
}

#[test]
fn other_frames_load() {
    let Some(dir) = data_dir() else { return };
    let seq = dir.join("sintel_alley1_frames_nogt");
    for i in 16..19 {
        let a = seq.join(format!("frame_{i:04}.png"));
        let b = seq.join(format!("frame_{:04}.png", i + 1));
        let (ia, _) = read_image_pair(&a, &b).unwrap();
        assert_eq!(ia.shape(), (3, 436, 1024));
    }
    for occ in ["0000000-occ_01.png", "0000000-occ_10.png"] {
        let im = read_image(&dir.join("flyingchairs_crops").join(occ)).unwrap();
        assert_eq!((im.height(), im.width()), (50, 50), "{occ}");
    }
    // Pairs of different sizes are refused, naming both files.
    let e = read_image_pair(
        &dir.join("kitti2015_000000/frame1.png"),
        &seq.join("frame_0016.png"),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("frame1.png") && e.contains("frame_0016.png"),
        "{e}"
    );
}

#[test]
fn float_formats_dispatch_by_extension() {
    use pins::io::{BitDepth, write_image};
    let dir = tempfile::tempdir().unwrap();
    let im = Image::from_vec(3, 4, 6, (0..72).map(|i| i as f32 / 50.0 - 0.2).collect()).unwrap();
    for ext in ["exr", "pfm", "npy", "EXR"] {
        let p = dir.path().join(format!("im.{ext}"));
        write_image(&p, &im, BitDepth::Eight).unwrap();
        assert_eq!(
            read_image(&p).unwrap(),
            im,
            "{ext}: floats are kept, depth ignored"
        );
    }
    // Nothing but the finished files is left in the directory.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 4);
}

/// CRC-32 as PNG uses it (bitwise; the files here are tiny).
fn crc32(data: &[u8]) -> u32 {
    let mut c = 0xffff_ffffu32;
    for &b in data {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xedb8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

/// A real 2x2 PNG whose IHDR is patched to declare `w`x`h`, with its CRC fixed.
fn png_declaring(w: u32, h: u32) -> Vec<u8> {
    use pins::io::{BitDepth, write_image};
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("tiny.png");
    write_image(&p, &Image::filled(1, 2, 2, 0.5), BitDepth::Eight).unwrap();
    let mut b = std::fs::read(&p).unwrap();
    assert_eq!(&b[12..16], b"IHDR");
    b[16..20].copy_from_slice(&w.to_be_bytes());
    b[20..24].copy_from_slice(&h.to_be_bytes());
    let crc = crc32(&b[12..29]);
    b[29..33].copy_from_slice(&crc.to_be_bytes());
    b
}

/// `pins simulate` on a small PNG declaring 16000x16000 is refused at once by the pixel budget,
/// naming the file, the declared size and the flag; `--max-pixels` moves the budget both ways.
#[test]
fn simulate_refuses_images_over_the_pixel_budget() {
    let dir = tempfile::tempdir().unwrap();
    let huge = dir.path().join("huge.png");
    std::fs::write(&huge, png_declaring(16000, 16000)).unwrap();
    let out = dir.path().join("out.png");
    let (h, o) = (huge.to_str().unwrap(), out.to_str().unwrap());
    let e = common::failed(&common::pins(&["simulate", "--in", h, "--out", o]));
    assert!(
        e.contains("huge.png") && e.contains("16000x16000") && e.contains("--max-pixels"),
        "{e}"
    );
    assert!(!out.exists());
    // A 1500x1000 frame: refused under 1 MP, simulated under 2 MP.
    let frame = dir.path().join("frame.png");
    pins::io::write_image(
        &frame,
        &Image::filled(1, 1000, 1500, 0.5),
        pins::io::BitDepth::Eight,
    )
    .unwrap();
    let f = frame.to_str().unwrap();
    let args = |budget: &'static str| {
        vec![
            "--max-pixels",
            budget,
            "simulate",
            "--in",
            f,
            "--out",
            o,
            "--psf",
            "delta",
        ]
    };
    let e = common::failed(&common::pins(&args("1000000")));
    assert!(e.contains("1500x1000") && e.contains("--max-pixels"), "{e}");
    assert!(!out.exists());
    common::ok(&common::pins(&args("2000000")));
    assert_eq!(read_image(&out).unwrap().shape(), (1, 1000, 1500));
}

/// A flow EXR (channels u, v) given to `pins simulate` as its image gets an image reader's
/// message, not one about PSF channels.
#[test]
fn two_channel_exr_as_image_names_its_channels() {
    let dir = tempfile::tempdir().unwrap();
    let flow = dir.path().join("flow.exr");
    pins::io::write_flow(&flow, &Flow::zeros(8, 8)).unwrap();
    let out = dir.path().join("o.png");
    let e = common::failed(&common::pins(&[
        "simulate",
        "--in",
        flow.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]));
    assert!(
        e.contains("flow.exr") && e.contains("an image needs") && e.contains("[u, v]"),
        "{e}"
    );
    assert!(!e.contains("PSF channels"), "{e}");
}

/// In every real flow file, a vector is either known (both components finite, below 1e9) or
/// unknown (both NaN): the readers never leave half a vector.
#[test]
fn real_flows_have_whole_unknown_vectors() {
    let Some(dir) = data_dir() else { return };
    let mut files: Vec<&str> = FLO.iter().map(|r| r.0).collect();
    files.push("kitti2015_000000/flow_gt.png");
    for rel in files {
        let f = read_flow(&dir.join(rel)).unwrap();
        let mut unknown = 0;
        for (&u, &v) in f.u().iter().zip(f.v()) {
            if u.is_nan() || v.is_nan() {
                assert!(u.is_nan() && v.is_nan(), "{rel}: ({u}, {v})");
                unknown += 1;
            } else {
                assert!(u.abs() < 1e9 && v.abs() < 1e9, "{rel}: ({u}, {v})");
            }
        }
        let expected = f.valid_mask().iter().filter(|&&m| !m).count();
        assert_eq!(unknown, expected, "{rel}");
    }
}

/// A real flow written as FlyingThings3D-style PFM reads back identical, through the
/// dispatcher both ways, unknown vectors included (Middlebury has some).
#[test]
fn real_flow_round_trips_through_pfm() {
    let Some(dir) = data_dir() else { return };
    let tmp = tempfile::tempdir().unwrap();
    for rel in [
        "middlebury_rubberwhale/flow10.flo",
        "flyingchairs_crops/00001_flow.flo",
    ] {
        let f = read_flow(&dir.join(rel)).unwrap();
        let p = tmp.path().join("f.pfm");
        pins::io::write_flow(&p, &f).unwrap();
        let back = read_flow(&p).unwrap();
        assert_eq!(back.valid_mask(), f.valid_mask(), "{rel}");
        for (a, b) in back.data().iter().zip(f.data()) {
            assert!(a == b || (a.is_nan() && b.is_nan()), "{rel}: {a} vs {b}");
        }
        let bytes = std::fs::read(&p).unwrap();
        let header = format!("PF\n{} {}\n-1.0\n", f.width(), f.height());
        assert!(bytes.starts_with(header.as_bytes()), "{rel}");
        assert_eq!(bytes.len(), header.len() + 12 * f.width() * f.height());
    }
}
