//! No panic from input: every image size through MMS, empty images, out-of-range flags, unknown
//! flow in tracking, and a corpus of malformed files through every command that reads a file,
//! none of which may end in a panic (exit code 101).

mod common;
use common::{failed, ok, pins};

use std::fs;
use std::path::{Path, PathBuf};

use pins::flow::infer::Predictor;
use pins::io::BitDepth;
use pins::{Flow, Image};

/// Where the real data of other projects lives (absent on a bare clone).
fn shared_data() -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
    if p.is_dir() {
        Some(p)
    } else {
        eprintln!(
            "skipping the real-data part: {} not found (it holds KITTI, Sintel, Middlebury)",
            p.display()
        );
        None
    }
}

/// A smooth test image whose second frame is the first moved right by one pixel.
fn pair(h: usize, w: usize) -> (Image, Image) {
    let make = |shift: f32| {
        let mut im = Image::zeros(3, h, w);
        for c in 0..3 {
            for y in 0..h {
                for x in 0..w {
                    let v =
                        0.5 + 0.4 * ((x as f32 - shift) * 0.3 + y as f32 * 0.2 + c as f32).sin();
                    im.set(c, y, x, v);
                }
            }
        }
        im
    };
    (make(0.0), make(1.0))
}

/// Every size from 1×1 on, every residue mod 8 on both axes, gives a finite flow of the size of
/// its images (sides that are 7 mod 8 once crashed the padding).
#[test]
fn mms_runs_on_every_image_size() {
    let predictor = Predictor::load("default").unwrap();
    let sides: Vec<usize> = (1..=16).chain([23, 31, 47]).collect();
    for &h in &sides {
        for &w in &sides {
            let (a, b) = pair(h, w);
            let flow = predictor
                .predict(&a, &b, 1)
                .unwrap_or_else(|e| panic!("{h}x{w}: {e}"));
            assert_eq!((flow.height(), flow.width()), (h, w));
            assert!(flow.data().iter().all(|v| v.is_finite()), "{h}x{w}");
        }
    }
}

/// From 128 px a side the coarse start runs the network at half size first: odd sizes there
/// give a finite flow of their images' size too.
#[test]
fn coarse_start_runs_on_odd_sizes() {
    let predictor = Predictor::load("default").unwrap();
    assert!(predictor.coarse_start);
    for (h, w) in [(128, 128), (129, 131), (135, 257), (257, 135)] {
        let (a, b) = pair(h, w);
        let flow = predictor
            .predict(&a, &b, 2)
            .unwrap_or_else(|e| panic!("{h}x{w}: {e}"));
        assert_eq!((flow.height(), flow.width()), (h, w));
        assert!(flow.data().iter().all(|v| v.is_finite()), "{h}x{w}");
    }
}

/// The command line on a size that is 7 mod 8 on one axis and 1 mod 8 on the other, and on the
/// real KITTI pair (375×1242) when it is there.
#[test]
fn infer_takes_odd_sizes_and_kitti_frames() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let (a, b) = pair(39, 57);
    let (p1, p2) = (t.join("a.png"), t.join("b.png"));
    pins::io::write_image(&p1, &a, BitDepth::Eight).unwrap();
    pins::io::write_image(&p2, &b, BitDepth::Eight).unwrap();
    let out = t.join("f.flo");
    ok(&pins(&[
        "infer",
        "--img1",
        p1.to_str().unwrap(),
        "--img2",
        p2.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--iters",
        "2",
    ]));
    let f = pins::io::read_flo(&out).unwrap();
    assert_eq!((f.width(), f.height()), (57, 39));
    let Some(data) = shared_data() else { return };
    let kitti = data.join("kitti2015_000000");
    let out = t.join("k.flo");
    ok(&pins(&[
        "infer",
        "--img1",
        kitti.join("frame1.png").to_str().unwrap(),
        "--img2",
        kitti.join("frame2.png").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--iters",
        "1",
    ]));
    let f = pins::io::read_flo(&out).unwrap();
    assert_eq!(f.height() % 8, 375 % 8);
    assert_eq!((f.width(), f.height()), (1242, 375));
}

/// An image with a zero side is a clear error with exit code 1, and nothing is written.
#[test]
fn empty_images_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let (a, _) = pair(16, 16);
    let good = t.join("good.png");
    pins::io::write_image(&good, &a, BitDepth::Eight).unwrap();
    // .npy arrays with a zero side, written by hand (numpy's layout, version 1.0).
    for (k, shape) in ["(3, 0, 16)", "(16, 0)", "(0, 0, 3)"].iter().enumerate() {
        let p = t.join(format!("e{k}.npy"));
        let dict = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {shape}, }}");
        let mut header = dict.into_bytes();
        while (10 + header.len() + 1) % 64 != 0 {
            header.push(b' ');
        }
        header.push(b'\n');
        let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
        bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
        bytes.extend_from_slice(&header);
        fs::write(&p, &bytes).unwrap();
        let out = t.join("o.png");
        let o = pins(&[
            "simulate",
            "--in",
            p.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(1), "simulate {shape}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.contains("empty") || err.contains("zero"),
            "{shape}: {err}"
        );
        assert!(!out.exists());
        let flo = t.join("o.flo");
        let o = pins(&[
            "infer",
            "--img1",
            p.to_str().unwrap(),
            "--img2",
            p.to_str().unwrap(),
            "--out",
            flo.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(1), "infer {shape}");
        assert!(!flo.exists());
    }
}

/// Negative and non-finite values reach validation and get its message, not clap's.
#[test]
fn out_of_range_flags_are_named() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let (a, _) = pair(16, 16);
    let img = t.join("a.png");
    pins::io::write_image(&img, &a, BitDepth::Eight).unwrap();
    let out = t.join("o.png");
    for (flag, value) in [
        ("--gamma", "-1"),
        ("--noise-a", "-0.5"),
        ("--brightness", "NaN"),
    ] {
        let err = failed(&pins(&[
            "simulate",
            "--in",
            img.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            flag,
            value,
        ]));
        assert!(
            !err.contains("unexpected argument"),
            "{flag} {value}: {err}"
        );
        let key = flag.trim_start_matches("--");
        assert!(
            err.contains(flag) || err.contains(&key.replace('-', ".")),
            "{flag} {value}: {err}"
        );
        assert!(!out.exists());
    }
    // A PSF with no centre pixel.
    let even = t.join("even.png");
    pins::io::write_image(&even, &Image::filled(1, 4, 6, 0.5), BitDepth::Eight).unwrap();
    let err = failed(&pins(&[
        "simulate",
        "--in",
        img.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--psf",
        even.to_str().unwrap(),
    ]));
    assert!(err.contains("odd"), "{err}");
    // An OS error is printed once.
    let err = failed(&pins(&[
        "simulate",
        "--in",
        "/no/such/image.png",
        "--out",
        out.to_str().unwrap(),
    ]));
    assert_eq!(err.matches("No such file").count(), 1, "{err}");
    // Tracking thresholds.
    let flows = t.join("flows");
    fs::create_dir_all(&flows).unwrap();
    for k in 0..3 {
        pins::io::write_flo(&flows.join(format!("{k:03}.flo")), &Flow::zeros(8, 8)).unwrap();
    }
    let settings = t.join("settings.json");
    for value in ["-1", "-0.5", "\"x\"", "null"] {
        fs::write(&settings, format!(r#"{{"threshold": {value}}}"#)).unwrap();
        let err = failed(&pins(&[
            "track",
            "--flows",
            flows.to_str().unwrap(),
            "--out",
            t.join("tr").to_str().unwrap(),
            "--config",
            settings.to_str().unwrap(),
        ]));
        assert!(err.contains("threshold"), "{value}: {err}");
        assert!(!t.join("tr/tracks.json").exists());
    }
}

/// Unknown vectors (Middlebury's ≥ 1e9, NaN) are invalid pixels in tracking, not an error.
#[test]
fn tracking_skips_unknown_flow() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let flows = t.join("flows");
    fs::create_dir_all(&flows).unwrap();
    for k in 0..6 {
        let mut f = Flow::zeros(40, 60);
        for y in 0..40 {
            for x in 0..10 {
                // Half Middlebury's "unknown" marker, half NaN.
                let v = if y < 20 { 1e10 } else { f32::NAN };
                f.set(y, x, v, v);
            }
        }
        for y in 15..25 {
            for x in 20 + 2 * k..30 + 2 * k {
                f.set(y, x, 2.0, 0.0);
            }
        }
        pins::io::write_flo(&flows.join(format!("{k:03}.flo")), &f).unwrap();
    }
    let out = t.join("tr");
    ok(&pins(&[
        "track",
        "--flows",
        flows.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--no-plots",
        "--horizons",
        "1",
    ]));
    let tracks: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(out.join("tracks.json")).unwrap()).unwrap();
    let objects = tracks["objects"].as_array().unwrap();
    assert_eq!(objects.len(), 1, "one mover, the unknown band is no object");
    // The mover's centroid in frame k is (24.5 + 2k, 19.5): the unknown band pulls it nowhere.
    for f in objects[0]["frames"].as_array().unwrap() {
        let k = f["frame"].as_f64().unwrap();
        let (x, y) = (
            f["centroid"][0].as_f64().unwrap(),
            f["centroid"][1].as_f64().unwrap(),
        );
        assert!(
            (x - 24.5 - 2.0 * k).abs() < 0.01 && (y - 19.5).abs() < 0.01,
            "frame {k}: centroid ({x}, {y})"
        );
    }
}

/// Malformed files through every command that reads one: a clear error (exit 1), never a panic
/// (exit 101) or a signal, and never an output file.
#[test]
fn malformed_inputs_never_panic() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let (a, _) = pair(24, 32);
    let good = t.join("good.png");
    pins::io::write_image(&good, &a, BitDepth::Eight).unwrap();
    let good_bytes = fs::read(&good).unwrap();
    let mut corpus: Vec<(String, Vec<u8>)> = vec![
        ("empty.png".into(), Vec::new()),
        ("zeros.png".into(), vec![0; 64]),
        (
            "garbage.png".into(),
            b"\x89PNG\r\n\x1a\nthis is not png".to_vec(),
        ),
        (
            "half.png".into(),
            good_bytes[..good_bytes.len() / 2].to_vec(),
        ),
        ("text.flo".into(), b"PIEH".to_vec()),
        ("huge.flo".into(), {
            let mut b = 202021.25f32.to_le_bytes().to_vec();
            b.extend_from_slice(&i32::MAX.to_le_bytes());
            b.extend_from_slice(&i32::MAX.to_le_bytes());
            b
        }),
        ("neg.flo".into(), {
            let mut b = 202021.25f32.to_le_bytes().to_vec();
            b.extend_from_slice(&(-4i32).to_le_bytes());
            b.extend_from_slice(&4i32.to_le_bytes());
            b
        }),
        ("bad.npy".into(), b"\x93NUMPY\x01\x00\xff\xff{".to_vec()),
        ("bad.pfm".into(), b"PF\n-3 99999999999\n-1.0\n".to_vec()),
        ("bad.exr".into(), b"v/1\x01\x02\x00\x00\x00garbage".to_vec()),
        ("bad.json".into(), b"{\"count\": -1, ".to_vec()),
        ("wrong.json".into(), b"[1, 2, 3]".to_vec()),
        ("nan.json".into(), b"{\"seed\": NaN}".to_vec()),
        (
            "bad.safetensors".into(),
            b"\xff\xff\xff\xff\xff\xff\xff\x7f{}".to_vec(),
        ),
    ];
    // A PNG declaring a huge size: its IHDR width and height patched, CRC left stale.
    let mut huge = good_bytes.clone();
    huge[16..20].copy_from_slice(&16000u32.to_be_bytes());
    huge[20..24].copy_from_slice(&16000u32.to_be_bytes());
    corpus.push(("huge.png".into(), huge));
    let dir_of = |name: &str, bytes: &[u8]| -> PathBuf {
        let d = t.join(format!("dir_{name}"));
        fs::create_dir_all(&d).unwrap();
        fs::write(d.join("00000_img1.png"), bytes).unwrap();
        fs::write(d.join("00000_img2.png"), bytes).unwrap();
        fs::write(d.join("00000_flow.flo"), bytes).unwrap();
        fs::write(d.join("000.flo"), bytes).unwrap();
        fs::write(d.join("001.flo"), bytes).unwrap();
        d
    };
    let out_dir = t.join("out");
    let o = out_dir.to_str().unwrap().to_string();
    let mut runs = 0;
    for (name, bytes) in &corpus {
        let f = t.join(name);
        fs::write(&f, bytes).unwrap();
        let f = f.to_str().unwrap().to_string();
        let d = dir_of(name, bytes);
        let d = d.to_str().unwrap().to_string();
        let g = good.to_str().unwrap().to_string();
        let commands: Vec<Vec<&str>> = vec![
            vec!["simulate", "--in", &f, "--out", "OUT.png"],
            vec!["simulate", "--in", &g, "--out", "OUT.png", "--psf", &f],
            vec!["simulate", "--in", &g, "--out", "OUT.png", "--config", &f],
            vec!["infer", "--img1", &f, "--img2", &g, "--out", "OUT.flo"],
            vec![
                "infer",
                "--weights",
                &f,
                "--img1",
                &g,
                "--img2",
                &g,
                "--out",
                "OUT.flo",
            ],
            vec!["infer", "--frames", &d, "--out", "OUT"],
            vec!["eval", "--data", &d, "--out", "OUT.json"],
            vec!["train", "--data", &d, "--out", "OUT"],
            vec!["train", "--config", &f, "--data", &d, "--out", "OUT"],
            vec!["generate", "--config", &f, "--out", "OUT"],
            vec!["track", "--flows", &d, "--out", "OUT"],
            vec!["track", "--frames", &d, "--out", "OUT"],
            vec!["track", "eval", "--tracks", &f, "--truth", &f],
            vec!["track", "render", "--config", &f, "--out", "OUT"],
            vec!["track", "experiment", "--config", &f, "--out", "OUT"],
            vec!["compare", &f, &g],
            vec!["array", "calibrate", "--grid", &f, "--out", "OUT.json"],
            vec![
                "array", "stitch", "--calib", &f, "--in", &g, "--out", "OUT.png",
            ],
            vec!["array", "render", "--in", &f, "--out", "OUT.png"],
        ];
        for cmd in commands {
            let _ = fs::remove_dir_all(&out_dir);
            let args: Vec<String> = cmd.iter().map(|s| s.replace("OUT", &o)).collect();
            let refs: Vec<&str> = args.iter().map(String::as_str).collect();
            let r = pins(&refs);
            runs += 1;
            let code = r.status.code();
            let err = String::from_utf8_lossy(&r.stderr);
            assert!(
                code.is_some() && code != Some(101),
                "{name}: `pins {}` ended with {:?}: {err}",
                refs.join(" "),
                r.status
            );
            assert!(!err.contains("panicked"), "{name}: {err}");
            if code != Some(0) {
                assert!(
                    !out_dir.exists() || fs::read_dir(&out_dir).unwrap().next().is_none(),
                    "{name}: `pins {}` failed but left {}",
                    refs.join(" "),
                    out_dir.display()
                );
                for ext in ["png", "flo", "json"] {
                    assert!(
                        !out_dir.with_extension(ext).exists(),
                        "{name}: `pins {}` failed but left a .{ext}",
                        refs.join(" ")
                    );
                }
            }
            let _ = ["png", "flo", "json"].map(|e| fs::remove_file(out_dir.with_extension(e)));
        }
    }
    eprintln!("{runs} malformed-input runs, none panicked");
}
