//! A loopback camera for the live tests: writes the ESP32 CameraWebServer's bytes exactly
//! (chunked, three chunks per frame, its boundary, X-Timestamp), with faults on request. All
//! traffic on 127.0.0.1; every server ends after a bounded number of connections.

#![allow(dead_code)]

use std::io::Write;
use std::net::{TcpListener, TcpStream};
use std::thread::JoinHandle;
use std::time::Duration;

pub const ESP32_BOUNDARY: &str = "123456789000000000000987654321";

/// A JPEG of a `w`×`h` frame with a bright square at (x, y) on a textured background.
pub fn jpeg(w: u32, h: u32, x: i64, y: i64) -> Vec<u8> {
    let mut rgb = vec![0u8; (w * h * 3) as usize];
    for j in 0..h as i64 {
        for i in 0..w as i64 {
            let inside = (i - x).abs() <= 8 && (j - y).abs() <= 8;
            let t = (((i * 7) ^ (j * 13)) % 61) as u8 + 40;
            let v = if inside {
                230 - ((i - x + j - y).rem_euclid(5) * 8) as u8
            } else {
                t
            };
            let k = ((j as u32 * w + i as u32) * 3) as usize;
            rgb[k] = v;
            rgb[k + 1] = v / 2 + 20;
            rgb[k + 2] = 255 - v;
        }
    }
    let mut out = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, 92)
        .encode(&rgb, w, h, image::ExtendedColorType::Rgb8)
        .expect("encode");
    out
}

/// Starts a server; `handler(k, stream)` serves connection `k` (0, 1, …) up to `max_conns`.
pub fn server<F>(max_conns: usize, handler: F) -> (String, JoinHandle<()>)
where
    F: Fn(usize, TcpStream) + Send + Sync + 'static,
{
    let l = TcpListener::bind("127.0.0.1:0").expect("bind");
    let addr = l.local_addr().expect("addr");
    let h = std::thread::spawn(move || {
        let handler = std::sync::Arc::new(handler);
        let mut threads = Vec::new();
        l.set_nonblocking(true).ok();
        let deadline = std::time::Instant::now() + Duration::from_secs(60);
        let mut k = 0;
        while k < max_conns && std::time::Instant::now() < deadline {
            match l.accept() {
                Ok((s, _)) => {
                    s.set_nonblocking(false).ok();
                    s.set_write_timeout(Some(Duration::from_secs(5))).ok();
                    let hd = handler.clone();
                    let kk = k;
                    threads.push(std::thread::spawn(move || hd(kk, s)));
                    k += 1;
                }
                Err(_) => std::thread::sleep(Duration::from_millis(10)),
            }
        }
        for t in threads {
            let _ = t.join();
        }
    });
    (format!("http://{addr}/stream"), h)
}

/// Reads the request head (bounded).
pub fn read_request(s: &mut TcpStream) {
    use std::io::Read;
    s.set_read_timeout(Some(Duration::from_secs(2))).ok();
    let mut buf = [0u8; 4096];
    let mut got = Vec::new();
    while !got.windows(4).any(|w| w == b"\r\n\r\n") && got.len() < 65536 {
        match s.read(&mut buf) {
            Ok(0) | Err(_) => break,
            Ok(n) => got.extend_from_slice(&buf[..n]),
        }
    }
}

/// The ESP32's response head.
pub fn esp32_head(s: &mut TcpStream) -> std::io::Result<()> {
    read_request(s);
    write!(
        s,
        "HTTP/1.1 200 OK\r\nContent-Type: multipart/x-mixed-replace;boundary={ESP32_BOUNDARY}\r\n\
         Transfer-Encoding: chunked\r\nAccess-Control-Allow-Origin: *\r\nX-Framerate: 60\r\n\r\n"
    )
}

/// One chunk of chunked transfer coding.
pub fn chunk(s: &mut TcpStream, data: &[u8]) -> std::io::Result<()> {
    write!(s, "{:X}\r\n", data.len())?;
    s.write_all(data)?;
    s.write_all(b"\r\n")
}

/// One frame as the ESP32 writes it: three chunks (part header, JPEG, boundary-ending CRLF).
/// `declared` overrides the Content-Length (a truncated frame keeps the real one).
pub fn esp32_part(s: &mut TcpStream, jpeg: &[u8], ts_us: u64) -> std::io::Result<()> {
    esp32_part_declared(s, jpeg, ts_us, jpeg.len() as u64)
}

pub fn esp32_part_declared(
    s: &mut TcpStream,
    jpeg: &[u8],
    ts_us: u64,
    declared: u64,
) -> std::io::Result<()> {
    let head = format!(
        "\r\n--{ESP32_BOUNDARY}\r\nContent-Type: image/jpeg\r\nContent-Length: {declared}\r\n\
         X-Timestamp: {}.{:06}\r\n\r\n",
        ts_us / 1_000_000,
        ts_us % 1_000_000
    );
    chunk(s, head.as_bytes())?;
    chunk(s, jpeg)?;
    chunk(s, b"\r\n")?;
    s.flush()
}

/// The comparable part of each line of a `tracks.jsonl`: frame, seq, time stamp and objects.
pub fn track_lines(path: &std::path::Path) -> Vec<serde_json::Value> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| {
            let v: serde_json::Value = serde_json::from_str(l).unwrap();
            serde_json::json!([v["frame"], v["seq"], v["timestamp_s"], v["objects"]])
        })
        .collect()
}
