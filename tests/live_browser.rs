//! The live view in a real headless browser: Debian's Chromium, driven by chromedriver over
//! the W3C WebDriver protocol, opens the page of `pins live --serve` while a loopback ESP32
//! camera streams; the page must load, show a frame (the MJPEG re-stream decoded by the
//! browser) and update its figures from the event stream. Skipped, with a message, where
//! chromium or chromedriver is absent. All traffic on 127.0.0.1, every loop bounded.

mod live_server;

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use live_server::{esp32_head, esp32_part, jpeg, server};

const FRAMES: usize = 150;

fn find(names: &[&str]) -> Option<String> {
    names.iter().find_map(|n| {
        Command::new(n)
            .arg("--version")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .ok()
            .filter(|s| s.success())
            .map(|_| n.to_string())
    })
}

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("a free port")
}

/// One HTTP/1.1 request with `Connection: close`; the JSON of the answer's body.
fn http_json(port: u16, method: &str, path: &str, body: &serde_json::Value) -> serde_json::Value {
    let mut s = TcpStream::connect(("127.0.0.1", port)).expect("connect to chromedriver");
    s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    let body = if method == "GET" || method == "DELETE" {
        String::new()
    } else {
        body.to_string()
    };
    write!(
        s,
        "{method} {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nContent-Type: application/json\r\n\
         Content-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    )
    .unwrap();
    // chromedriver keeps the connection open whatever the request says: read the head, then
    // exactly Content-Length bytes.
    let mut r = BufReader::new(s);
    let mut length = 0usize;
    let mut head = String::new();
    for _ in 0..100 {
        let mut l = String::new();
        if r.read_line(&mut l).unwrap_or(0) == 0 || l == "\r\n" {
            break;
        }
        if let Some((k, v)) = l.split_once(':')
            && k.eq_ignore_ascii_case("content-length")
        {
            length = v.trim().parse().unwrap_or(0);
        }
        head += &l;
    }
    let mut body = vec![0u8; length.min(1 << 26)];
    r.read_exact(&mut body)
        .unwrap_or_else(|e| panic!("chromedriver's answer cut short ({e}): {head}"));
    let text = String::from_utf8_lossy(&body);
    let json = if text.trim().is_empty() {
        "null"
    } else {
        text.trim()
    };
    serde_json::from_str(json).unwrap_or_else(|e| panic!("chromedriver answered {head}{text}: {e}"))
}

/// Kills a child process when dropped (a failing assertion must not leave a browser behind).
struct Guard(Child);

impl Drop for Guard {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[test]
fn the_live_view_shows_frames_and_updates_in_chromium() {
    let (Some(chromium), Some(driver)) = (
        find(&["chromium", "chromium-browser"]),
        find(&["chromedriver"]),
    ) else {
        eprintln!(
            "SKIPPED: chromium and chromedriver not found (Debian: apt-get install chromium \
             chromium-driver); .ci/run installs them"
        );
        return;
    };
    // The browser first (its start can take a while on a loaded machine), then the camera.
    let port = free_port();
    let _driver = Guard(
        Command::new(&driver)
            .arg(format!("--port={port}"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("start chromedriver"),
    );
    let deadline = Instant::now() + Duration::from_secs(20);
    while TcpStream::connect(("127.0.0.1", port)).is_err() {
        assert!(Instant::now() < deadline, "chromedriver never listened");
        std::thread::sleep(Duration::from_millis(100));
    }
    let profile = tempfile::tempdir().unwrap();
    let args = [
        "--headless=new".to_string(),
        "--no-sandbox".into(),
        "--disable-gpu".into(),
        "--disable-quic".into(),
        "--no-first-run".into(),
        "--disable-background-networking".into(),
        "--disable-component-update".into(),
        "--disable-sync".into(),
        "--disable-dev-shm-usage".into(),
        format!("--user-data-dir={}", profile.path().display()),
    ];
    let session = http_json(
        port,
        "POST",
        "/session",
        &serde_json::json!({"capabilities": {"alwaysMatch": {
            "browserName": "chrome",
            // The page never finishes loading (its image is an endless MJPEG stream).
            "pageLoadStrategy": "eager",
            "goog:chromeOptions": {"binary": which(&chromium), "args": args}
        }}}),
    );
    let id = session["value"]["sessionId"]
        .as_str()
        .unwrap_or_else(|| panic!("no WebDriver session: {session}"))
        .to_string();
    // The camera: a square crossing the frame, a frame every 200 ms for 30 s (the test ends it
    // as soon as the page has shown what it must).
    let frames: Vec<Vec<u8>> = (0..FRAMES)
        .map(|k| jpeg(160, 120, 20 + (k as i64 % 40) * 3, 60))
        .collect();
    let (url, camera) = server(1, move |_, mut s| {
        if esp32_head(&mut s).is_err() {
            return;
        }
        for (k, f) in frames.iter().enumerate() {
            if esp32_part(&mut s, f, 1_000_000 + k as u64 * 200_000).is_err() {
                return;
            }
            std::thread::sleep(Duration::from_millis(200));
        }
    });
    let mut live = Guard(
        Command::new(env!("CARGO_BIN_EXE_pins"))
            .args([
                "live",
                "--url",
                &url,
                "--iters",
                "2",
                "--confirm",
                "2",
                "--quiet",
            ])
            .args(["--duration", "60", "--max-frames", &FRAMES.to_string()])
            .args(["--serve", "127.0.0.1:0"])
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start pins live"),
    );
    let mut err = BufReader::new(live.0.stderr.take().unwrap());
    let mut view = None;
    for _ in 0..20 {
        let mut l = String::new();
        if err.read_line(&mut l).unwrap_or(0) == 0 {
            break;
        }
        if let Some(a) = l.trim().strip_prefix("live: view at ") {
            view = Some(a.to_string());
            break;
        }
    }
    let view = view.expect("the view's address on stderr");
    // Keep reading pins' stderr so it never blocks on a full pipe.
    std::thread::spawn(move || for _ in err.lines() {});

    let go = http_json(
        port,
        "POST",
        &format!("/session/{id}/url"),
        &serde_json::json!({ "url": view }),
    );
    assert!(go["value"].is_null(), "navigation failed: {go}");
    // Poll the page: the frame number it shows, the decoded image's width, the figures.
    let probe = serde_json::json!({
        "script": "return [document.title, document.body.dataset.frame || null, \
                   document.getElementById('view').naturalWidth, \
                   document.getElementById('figures').innerText];",
        "args": []
    });
    let mut seen_frames = Vec::new();
    let mut width = 0;
    let mut last = serde_json::Value::Null;
    let deadline = Instant::now() + Duration::from_secs(30);
    while Instant::now() < deadline {
        let r = http_json(port, "POST", &format!("/session/{id}/execute/sync"), &probe);
        last = r["value"].clone();
        assert_eq!(last[0], "pins live", "{r}");
        if let Some(f) = last[1].as_str().and_then(|f| f.parse::<u64>().ok())
            && seen_frames.last() != Some(&f)
        {
            seen_frames.push(f);
        }
        width = width.max(last[2].as_u64().unwrap_or(0));
        if seen_frames.len() >= 3 && width > 0 {
            break;
        }
        std::thread::sleep(Duration::from_millis(150));
    }
    let _ = http_json(
        port,
        "DELETE",
        &format!("/session/{id}"),
        &serde_json::Value::Null,
    );
    // A frame was shown (the browser decoded a JPEG of the re-stream) and the figures moved
    // on at least twice as frames were processed.
    assert!(width > 0, "no frame shown: {last}");
    assert!(
        seen_frames.len() >= 3 && seen_frames.windows(2).all(|w| w[0] < w[1]),
        "the page did not update: frames {seen_frames:?}, last {last}"
    );
    assert!(
        last[3]
            .as_str()
            .is_some_and(|t| t.contains("processed fps")),
        "{last}"
    );
    drop(live);
    let _ = camera.join();
}

/// The absolute path of a program on PATH (chromedriver wants the binary's path).
fn which(name: &str) -> String {
    std::env::var_os("PATH")
        .and_then(|p| {
            std::env::split_paths(&p)
                .map(|d| d.join(name))
                .find(|f| f.is_file())
        })
        .map(|f| f.display().to_string())
        .unwrap_or_else(|| name.to_string())
}
