//! An independently written camera: ffmpeg's MJPEG-over-HTTP muxer (`-f mpjpeg -listen 1`)
//! serving a folder of JPEGs, read by `pins live --url`. ffmpeg writes its own boundary, header
//! case and part layout (`Content-length`, no X-Timestamp, no chunked encoding), so this checks
//! the client against bytes pins did not write. Skipped, with a message, where ffmpeg is absent.

mod live_server;

use std::net::TcpListener;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use live_server::jpeg;

const FRAMES: usize = 8;

/// A free loopback port (bound, read, released: ffmpeg binds it next).
fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("a free port")
}

/// Whether a socket listens on 127.0.0.1:`port` (Linux's /proc/net/tcp: local address
/// `0100007F:PORT` in hex, state 0A).
fn listening(port: u16) -> bool {
    let key = format!("0100007F:{port:04X}");
    std::fs::read_to_string("/proc/net/tcp").is_ok_and(|t| {
        t.lines().any(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            f.len() > 3 && f[1] == key && f[3] == "0A"
        })
    })
}

fn ffmpeg_present() -> bool {
    Command::new("ffmpeg")
        .arg("-version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

#[test]
fn ffmpeg_mpjpeg_server_is_read_and_recorded() {
    if !ffmpeg_present() {
        eprintln!(
            "SKIPPED: ffmpeg not found (Debian: apt-get install ffmpeg); .ci/run installs it"
        );
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let frames = dir.path().join("frames");
    std::fs::create_dir_all(&frames).unwrap();
    for k in 0..FRAMES {
        std::fs::write(
            frames.join(format!("{k:03}.jpg")),
            jpeg(160, 120, 40 + 3 * k as i64, 60),
        )
        .unwrap();
    }
    for (boundary, quoted) in [("ffserverframe", false), ("pins frame", true)] {
        let port = free_port();
        let url = format!("http://127.0.0.1:{port}/stream");
        let content_type = if quoted {
            format!("multipart/x-mixed-replace;boundary=\"{boundary}\"")
        } else {
            format!("multipart/x-mixed-replace;boundary={boundary}")
        };
        // -re: at the frame rate, as a camera would; the frames are copied, not re-encoded.
        let mut server = Command::new("ffmpeg")
            .args([
                "-hide_banner",
                "-loglevel",
                "error",
                "-re",
                "-framerate",
                "10",
            ])
            .arg("-i")
            .arg(frames.join("%03d.jpg"))
            .args(["-c:v", "copy", "-f", "mpjpeg", "-boundary_tag", boundary])
            .args(["-content_type", &content_type, "-listen", "1", &url])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("start ffmpeg");
        // ffmpeg serves one client and exits: wait (bounded) until it listens without
        // connecting, by reading the kernel's socket table.
        let deadline = Instant::now() + Duration::from_secs(20);
        while !listening(port) && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(50));
        }
        assert!(listening(port), "ffmpeg never listened on {url}");
        let out = dir.path().join(format!("out-{quoted}"));
        let rec = dir.path().join(format!("rec-{quoted}"));
        let o = Command::new(env!("CARGO_BIN_EXE_pins"))
            .args(["live", "--url", &url, "--iters", "2", "--quiet"])
            .args(["--duration", "60", "--max-frames", "4"])
            .arg("--record")
            .arg(&rec)
            .arg("--out")
            .arg(&out)
            .output()
            .expect("run pins live");
        let _ = server.kill();
        let _ = server.wait();
        assert!(
            o.status.success(),
            "pins live on ffmpeg ({boundary:?}): {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let lines = std::fs::read_to_string(out.join("tracks.jsonl")).unwrap();
        // Four frames received, three flows (the first frame only starts the sequence).
        assert_eq!(lines.lines().count(), 3, "{lines}");
        for l in lines.lines() {
            let v: serde_json::Value = serde_json::from_str(l).unwrap();
            assert!(v["objects"].is_array(), "{l}");
        }
        // The recording holds the JPEGs ffmpeg sent, byte for byte.
        let mut recorded: Vec<_> = std::fs::read_dir(rec.join("frames"))
            .unwrap()
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "jpg"))
            .collect();
        recorded.sort();
        assert!(recorded.len() >= 4, "{recorded:?}");
        let sent: Vec<Vec<u8>> = (0..FRAMES)
            .map(|k| std::fs::read(frames.join(format!("{k:03}.jpg"))).unwrap())
            .collect();
        for r in &recorded {
            let bytes = std::fs::read(r).unwrap();
            assert!(
                sent.contains(&bytes),
                "{} is not one of the frames sent",
                r.display()
            );
        }
    }
}
