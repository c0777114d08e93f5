//! End to end: a moving scene served as the ESP32 would serve it gives the same tracks live
//! (`pins live --url … --record R`) as from the recording (`pins live --replay R`); the browser
//! view's endpoints answer while a live run is going.

mod live_server;

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use live_server::{esp32_head, esp32_part, jpeg, server, track_lines};

const FRAMES: usize = 10;

/// The scene: a bright square crossing a textured background, 3 px per frame.
fn scene() -> Vec<Vec<u8>> {
    (0..FRAMES)
        .map(|k| jpeg(160, 120, 40 + 3 * k as i64, 60))
        .collect()
}

fn camera(pause: Duration) -> (String, std::thread::JoinHandle<()>) {
    let frames = scene();
    server(1, move |_, mut s| {
        if esp32_head(&mut s).is_err() {
            return;
        }
        for (k, f) in frames.iter().enumerate() {
            if esp32_part(&mut s, f, 5_000_000 + k as u64 * 66_667).is_err() {
                return;
            }
            std::thread::sleep(pause);
        }
        std::thread::sleep(Duration::from_secs(2));
    })
}

fn pins() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_pins"));
    c.args(["live", "--iters", "4", "--confirm", "2", "--quiet"]);
    c
}

#[test]
fn live_and_replay_give_the_same_tracks() {
    let dir = tempfile::tempdir().unwrap();
    let (rec, live_out, replay_out) = (
        dir.path().join("rec"),
        dir.path().join("live"),
        dir.path().join("replay"),
    );
    let (url, h) = camera(Duration::from_millis(250));
    let st = pins()
        .args([
            "--url",
            &url,
            "--duration",
            "60",
            "--max-frames",
            &FRAMES.to_string(),
        ])
        .arg("--record")
        .arg(&rec)
        .arg("--out")
        .arg(&live_out)
        .status()
        .unwrap();
    assert!(st.success());
    h.join().unwrap();
    let st = pins()
        .arg("--replay")
        .arg(&rec)
        .arg("--out")
        .arg(&replay_out)
        .status()
        .unwrap();
    assert!(st.success());
    let (a, b) = (
        track_lines(&live_out.join("tracks.jsonl")),
        track_lines(&replay_out.join("tracks.jsonl")),
    );
    assert!(!a.is_empty());
    assert_eq!(a, b, "live and replay differ");
    assert!(!live_out.join("tracks.jsonl.part").exists());
    // Velocities are in pixels per second of the camera's clock: the square moves 3 px per
    // 66.667 ms, 45 px/s, once a track is confirmed.
    let last: serde_json::Value = serde_json::from_str(
        std::fs::read_to_string(live_out.join("tracks.jsonl"))
            .unwrap()
            .lines()
            .last()
            .unwrap(),
    )
    .unwrap();
    eprintln!("last live line: {last}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(live_out.join("summary.json")).unwrap())
            .unwrap();
    eprintln!("summary: {summary}");
}

fn http_get(addr: &str, path: &str, max: usize) -> String {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    write!(s, "GET {path} HTTP/1.1\r\nHost: {addr}\r\n\r\n").unwrap();
    let mut buf = vec![0u8; max];
    let mut got = 0;
    let end = Instant::now() + Duration::from_secs(10);
    while got < max && Instant::now() < end {
        match s.read(&mut buf[got..]) {
            Ok(0) | Err(_) => break,
            Ok(n) => got += n,
        }
    }
    String::from_utf8_lossy(&buf[..got]).to_string()
}

#[test]
fn the_browser_view_serves_the_page_the_frames_and_the_figures() {
    let (url, h) = camera(Duration::from_millis(300));
    let mut child = pins()
        .args([
            "--url",
            &url,
            "--duration",
            "60",
            "--max-frames",
            &FRAMES.to_string(),
        ])
        .args(["--serve", "127.0.0.1:0"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut err = BufReader::new(child.stderr.take().unwrap());
    let mut addr = None;
    for _ in 0..20 {
        let mut l = String::new();
        if err.read_line(&mut l).unwrap_or(0) == 0 {
            break;
        }
        if let Some(a) = l.trim().strip_prefix("live: view at http://") {
            addr = Some(a.trim_end_matches('/').to_string());
            break;
        }
    }
    let addr = addr.expect("the view's address on stderr");
    let page = http_get(&addr, "/", 1 << 16);
    assert!(
        page.starts_with("HTTP/1.1 200") && page.contains("EventSource('/events')"),
        "{page}"
    );
    let events = http_get(&addr, "/events", 600);
    assert!(
        events.contains("text/event-stream") && events.contains("data: {"),
        "{events}"
    );
    let mjpeg = http_get(&addr, "/stream.mjpg", 1 << 14);
    assert!(
        mjpeg.contains("multipart/x-mixed-replace;boundary=pinsliveframe"),
        "{mjpeg}"
    );
    assert!(
        mjpeg.contains("--pinsliveframe\r\nContent-Type: image/jpeg"),
        "{mjpeg}"
    );
    let stats = http_get(&addr, "/stats.json", 1 << 16);
    assert!(stats.contains("\"processed_fps\""), "{stats}");
    assert!(http_get(&addr, "/nothing", 4096).starts_with("HTTP/1.1 404"));
    let end = Instant::now() + Duration::from_secs(60);
    while child.try_wait().unwrap().is_none() && Instant::now() < end {
        std::thread::sleep(Duration::from_millis(50));
    }
    let st = child.try_wait().unwrap();
    if st.is_none() {
        let _ = child.kill();
    }
    assert!(st.is_some_and(|s| s.success()));
    h.join().unwrap();
}

/// The live pipeline and `pins track --frames` on the same frames find the same objects at the
/// same places with the same forecasts: one tracker, whichever command feeds it.
#[test]
fn live_on_a_folder_tracks_as_pins_track_does() {
    let dir = tempfile::tempdir().unwrap();
    let frames = dir.path().join("frames");
    std::fs::create_dir_all(&frames).unwrap();
    for (k, f) in scene().iter().enumerate() {
        std::fs::write(frames.join(format!("{k:05}.jpg")), f).unwrap();
    }
    let (live_out, track_out) = (dir.path().join("live"), dir.path().join("track"));
    let st = pins()
        .arg("--frames")
        .arg(&frames)
        .args(["--fps", "15", "--horizons", "1,5"])
        .arg("--out")
        .arg(&live_out)
        .status()
        .unwrap();
    assert!(st.success());
    let o = Command::new(env!("CARGO_BIN_EXE_pins"))
        .args([
            "track",
            "--iters",
            "4",
            "--confirm",
            "2",
            "--horizons",
            "1,5",
            // `pins live`'s own flow without --config: stage 3 at the frame's size.
            "--weights",
            "mms-small",
            "--scale",
            "1",
        ])
        .arg("--frames")
        .arg(&frames)
        .arg("--out")
        .arg(&track_out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let tracked: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(track_out.join("tracks.json")).unwrap())
            .unwrap();
    let mut compared = 0;
    for line in std::fs::read_to_string(live_out.join("tracks.jsonl"))
        .unwrap()
        .lines()
    {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        let frame = v["frame"].as_u64().unwrap();
        for obj in v["objects"].as_array().unwrap() {
            let track = tracked["objects"]
                .as_array()
                .unwrap()
                .iter()
                .find(|t| t["id"] == obj["id"])
                .unwrap_or_else(|| panic!("live object {obj} has no track in {tracked}"));
            let rec = track["frames"]
                .as_array()
                .unwrap()
                .iter()
                .find(|r| r["frame"].as_u64() == Some(frame))
                .unwrap_or_else(|| panic!("frame {frame} of {obj} missing from pins track"));
            for (a, b) in [
                (&obj["centroid"], &rec["centroid"]),
                (&obj["predicted"]["1"], &rec["predicted"]["1"]),
                (&obj["predicted"]["5"], &rec["predicted"]["5"]),
            ] {
                for k in 0..2 {
                    let (x, y) = (a[k].as_f64().unwrap(), b[k].as_f64().unwrap());
                    assert!(
                        (x - y).abs() < 1e-3,
                        "frame {frame}: live {a} against track {b}"
                    );
                }
            }
            compared += 1;
        }
    }
    assert!(compared >= 3, "too few tracked frames compared: {compared}");

    // The same settings from one config file: `pins live --config` and `pins track --config`
    // give what their flags gave.
    let cfg = dir.path().join("track.json");
    std::fs::write(
        &cfg,
        r#"{"profile": "estimated", "flow": {"iters": 4, "weights": "mms-small", "scale": 1},
            "tracker": {"confirm": 2}, "horizons": [1, 5]}"#,
    )
    .unwrap();
    let (live_cfg, track_cfg) = (dir.path().join("live_cfg"), dir.path().join("track_cfg"));
    for (args, out) in [
        (vec!["live", "--quiet", "--fps", "15"], &live_cfg),
        (vec!["track"], &track_cfg),
    ] {
        let o = Command::new(env!("CARGO_BIN_EXE_pins"))
            .args(args)
            .arg("--frames")
            .arg(&frames)
            .arg("--config")
            .arg(&cfg)
            .arg("--out")
            .arg(out)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let objects = |path: &std::path::Path| -> Vec<serde_json::Value> {
        std::fs::read_to_string(path)
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap()["objects"].clone())
            .collect()
    };
    assert_eq!(
        objects(&live_cfg.join("tracks.jsonl")),
        objects(&live_out.join("tracks.jsonl"))
    );
    let without_time = |path: &std::path::Path| {
        let mut v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
        v["ms_per_frame"] = serde_json::Value::Null;
        v
    };
    assert_eq!(
        without_time(&track_cfg.join("tracks.json")),
        without_time(&track_out.join("tracks.json"))
    );
}
