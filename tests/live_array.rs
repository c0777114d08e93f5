//! End to end through the 3-lens array (Notes S1, S3): a moving wide scene rendered to the
//! sensor by `pins array render`, served as the ESP32 would serve it, stitched with the
//! calibration from `pins array calibrate`, flowed by MMS and tracked, gives the same tracks
//! live (`pins live --url … --calib`) as from its recording (`pins live --replay`) and as
//! `pins track --frames` on the recorded frames stitched by `pins array stitch`, and the
//! track follows the object's true centre in the wide image.

mod live_server;

use std::path::Path;
use std::process::Command;
use std::time::Duration;

use live_server::{esp32_head, esp32_part, server, track_lines};

const FRAMES: usize = 8;

fn pins(args: &[&str]) {
    let o = Command::new(env!("CARGO_BIN_EXE_pins"))
        .args(args)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "pins {args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The raw sensor frames (JPEG) of a disc crossing the 1440×480 wide scene, the calibration,
/// and the disc's true centres in the wide image.
fn camera_frames(dir: &Path) -> (Vec<Vec<u8>>, std::path::PathBuf, Vec<[f64; 2]>) {
    let scene = dir.join("scene.json");
    std::fs::write(
        &scene,
        format!(
            r#"{{"scene": {{"width": 1440, "height": 480, "fps": 15, "frames": {FRAMES},
                "seed": 5, "objects": [{{"path": "line", "radius": 28,
                "from": [0.4, 0.5], "to": [0.5, 0.46]}}]}}, "save_clean": true}}"#
        ),
    )
    .unwrap();
    let clip = dir.join("clip");
    pins(&["track", "render", "--config", s(&scene), "--out", s(&clip)]);
    let (grid, calib) = (dir.join("grid.png"), dir.join("calib.json"));
    pins(&["array", "render", "--grid", "--out", s(&grid)]);
    pins(&["array", "calibrate", "--grid", s(&grid), "--out", s(&calib)]);
    let jpegs = (0..FRAMES)
        .map(|k| {
            let (clean, raw) = (
                clip.join("clean").join(format!("{k:05}.png")),
                dir.join(format!("raw{k:05}.png")),
            );
            let seed = k.to_string();
            pins(&[
                "array",
                "render",
                "--in",
                s(&clean),
                "--out",
                s(&raw),
                "--seed",
                &seed,
            ]);
            let rgb = image::open(&raw).unwrap().to_rgb8();
            let mut out = Vec::new();
            image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, 92)
                .encode(
                    &rgb,
                    rgb.width(),
                    rgb.height(),
                    image::ExtendedColorType::Rgb8,
                )
                .unwrap();
            out
        })
        .collect();
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(clip.join("truth.json")).unwrap()).unwrap();
    let centres = truth["objects"][0]["centroids"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| [c[0].as_f64().unwrap(), c[1].as_f64().unwrap()])
        .collect();
    (jpegs, calib, centres)
}

#[test]
#[ignore = "system tier (cargo test --release -- --ignored): a live run paced by the camera, minutes"]
fn array_frames_are_stitched_flowed_and_tracked_live_as_from_the_recording() {
    let dir = tempfile::tempdir().unwrap();
    let (jpegs, calib, centres) = camera_frames(dir.path());
    let (url, h) = server(1, move |_, mut st| {
        if esp32_head(&mut st).is_err() {
            return;
        }
        for (k, f) in jpegs.iter().enumerate() {
            if esp32_part(&mut st, f, 5_000_000 + k as u64 * 66_667).is_err() {
                return;
            }
            // Slower than an idle machine's pipeline: usually no frame is dropped.
            std::thread::sleep(Duration::from_millis(2500));
        }
        std::thread::sleep(Duration::from_secs(2));
    });
    let (rec, live, replay) = (
        dir.path().join("rec"),
        dir.path().join("live"),
        dir.path().join("replay"),
    );
    let common = [
        "live",
        "--iters",
        "4",
        "--confirm",
        "2",
        "--quiet",
        "--calib",
    ];
    let frames = FRAMES.to_string();
    let mut args: Vec<&str> = common.to_vec();
    args.extend([
        s(&calib),
        "--url",
        &url,
        "--duration",
        "120",
        "--max-frames",
        &frames,
    ]);
    args.extend(["--record", s(&rec), "--out", s(&live)]);
    pins(&args);
    h.join().unwrap();
    let mut args: Vec<&str> = common.to_vec();
    args.extend([s(&calib), "--replay", s(&rec), "--out", s(&replay)]);
    pins(&args);
    let (a, b) = (
        track_lines(&live.join("tracks.jsonl")),
        track_lines(&replay.join("tracks.jsonl")),
    );
    // A frame the pipeline was too busy for is dropped live and skipped in the replay too, so
    // live and replay agree whatever the machine's load.
    assert!(!a.is_empty(), "no processed frame");
    assert_eq!(a, b, "live and replay differ");
    // The recording keeps every frame received, dropped or not: stitched to files and tracked
    // by `pins track --frames`, it must follow the disc's true centre in the wide image. This
    // sees every pair, so it does not depend on which frames a busy pipeline dropped.
    let frames = rec.join("frames");
    let recorded = std::fs::read_dir(&frames).unwrap().count();
    assert_eq!(recorded, FRAMES, "the recording misses frames");
    let (stitched, tracked) = (dir.path().join("stitched"), dir.path().join("tracked"));
    pins(&[
        "array",
        "stitch",
        "--calib",
        s(&calib),
        "--in",
        s(&frames),
        "--out",
        s(&stitched),
    ]);
    pins(&[
        "track",
        "--iters",
        "4",
        "--confirm",
        "2",
        // `pins live`'s own flow without --config: stage 3 at the frame's size.
        "--weights",
        "mms-small",
        "--scale",
        "1",
        "--frames",
        s(&stitched),
        "--out",
        s(&tracked),
        "--no-plots",
    ]);
    let t: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(tracked.join("tracks.json")).unwrap())
            .unwrap();
    let objects = t["objects"].as_array().unwrap();
    assert_eq!(objects.len(), 1, "one disc, tracks: {t}");
    let records = objects[0]["frames"].as_array().unwrap();
    let mut worst = 0.0f64;
    for r in records {
        let frame = r["frame"].as_u64().unwrap() as usize;
        let c = [
            r["centroid"][0].as_f64().unwrap(),
            r["centroid"][1].as_f64().unwrap(),
        ];
        let truth = centres[frame];
        let err = (c[0] - truth[0]).hypot(c[1] - truth[1]);
        assert!(err < 6.0, "frame {frame}: centre {c:?}, truth {truth:?}");
        worst = worst.max(err);
    }
    // Confirmed within the first frames and followed to the end.
    assert!(
        records.len() >= FRAMES - 4,
        "tracked in {} of {} frames",
        records.len(),
        FRAMES - 1
    );
    eprintln!(
        "pins track on the stitched recording: tracked in {} frames, centre within {worst:.2} px",
        records.len()
    );
    // When the live run processed every frame it saw the same pairs, and its tracks are those
    // of `pins track` (8-bit stitched PNGs there, floats live).
    if a.len() + 1 != FRAMES {
        eprintln!(
            "SKIPPED the live against pins track comparison: the busy pipeline processed {} of {} pairs",
            a.len(),
            FRAMES - 1
        );
        return;
    }
    let mut diff = 0.0f64;
    for line in &a {
        let frame = line[0].as_u64().unwrap();
        let live_objects = line[3].as_array().unwrap();
        assert!(live_objects.len() <= 1, "frame {frame}: {live_objects:?}");
        for o in live_objects {
            let rec = records
                .iter()
                .find(|r| r["frame"].as_u64() == Some(frame))
                .unwrap_or_else(|| panic!("frame {frame} missing from pins track: {t}"));
            for k in 0..2 {
                let d = o["centroid"][k].as_f64().unwrap() - rec["centroid"][k].as_f64().unwrap();
                diff = diff.max(d.abs());
            }
        }
    }
    eprintln!("live: centres within {diff:.3} px of pins track");
    assert!(diff < 0.25, "pins track and live differ by {diff} px");
}
