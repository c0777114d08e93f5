//! The MJPEG client against a loopback ESP32 with injected faults: truncated JPEG, a stall,
//! a drop mid-frame, a server that never answers, `boundary=frame` without Content-Length, an
//! absurd Content-Length, a frame-size change, and refused answers.

mod live_server;

use std::io::Write;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use live_server::{esp32_head, esp32_part, jpeg, read_request, server};
use pins::live::reader::{Frame, Reader, ReaderConfig};
use pins::live::url::HttpUrl;

fn config(url: &str) -> ReaderConfig {
    let mut c = ReaderConfig::new(HttpUrl::parse(url).unwrap());
    c.timeouts.read = Duration::from_millis(500);
    c.timeouts.response = Duration::from_millis(500);
    c.backoff_min = Duration::from_millis(50);
    c.backoff_max = Duration::from_millis(200);
    c.quiet = true;
    c
}

/// Takes frames until `want` have been received in all or `secs` pass.
fn collect(r: &Reader, want: u64, secs: f64) -> Vec<Frame> {
    let end = Instant::now() + Duration::from_secs_f64(secs);
    let mut got = Vec::new();
    while Instant::now() < end {
        if let Some(f) = r.latest.take(Duration::from_millis(50)) {
            got.push(f);
        }
        let c = r.latest.counters.snapshot();
        if c.received >= want && c.received == got.len() as u64 + c.dropped {
            break;
        }
    }
    got
}

#[test]
fn esp32_frames_arrive_whole_with_their_timestamps() {
    let (url, h) = server(1, |_, mut s| {
        esp32_head(&mut s).ok();
        for k in 0..5u64 {
            esp32_part(
                &mut s,
                &jpeg(64, 48, 10 + 5 * k as i64, 20),
                12_000_000 + k * 66_667,
            )
            .ok();
            std::thread::sleep(Duration::from_millis(30));
        }
        std::thread::sleep(Duration::from_millis(300));
    });
    let r = Reader::start(config(&url), Arc::new(AtomicBool::new(false)), None).unwrap();
    let got = collect(&r, 5, 10.0);
    let c = r.latest.counters.snapshot();
    assert_eq!((c.received, c.bad), (5, 0), "{c:?}");
    assert_eq!(got.len() as u64 + c.dropped, 5);
    let last = got.last().unwrap();
    assert_eq!(last.image.shape(), (3, 48, 64));
    assert!((last.camera_s.unwrap() - (12.0 + 4.0 * 0.066667)).abs() < 1e-6);
    r.stop();
    h.join().unwrap();
}

#[test]
fn a_truncated_and_a_corrupt_jpeg_are_skipped_and_counted() {
    let (url, h) = server(1, |_, mut s| {
        esp32_head(&mut s).ok();
        let good = jpeg(64, 48, 20, 20);
        esp32_part(&mut s, &good, 1_000_000).ok();
        // The driver's buffer was too small: the frame ends early, without FF D9.
        esp32_part(&mut s, &good[..good.len() / 2], 1_100_000).ok();
        let mut corrupt = good.clone();
        for b in corrupt[200..400].iter_mut() {
            *b = 0xFF;
        }
        esp32_part(&mut s, &corrupt, 1_150_000).ok();
        esp32_part(&mut s, &good, 1_200_000).ok();
        std::thread::sleep(Duration::from_millis(300));
    });
    let r = Reader::start(config(&url), Arc::new(AtomicBool::new(false)), None).unwrap();
    let got = collect(&r, 2, 10.0);
    let c = r.latest.counters.snapshot();
    assert_eq!(c.received, 2, "{c:?}");
    assert!(c.bad >= 1, "{c:?}");
    assert!(got.iter().all(|f| f.image.shape() == (3, 48, 64)));
    r.stop();
    h.join().unwrap();
}

#[test]
fn a_stall_and_a_drop_mid_frame_are_followed_by_reconnections() {
    let (url, h) = server(3, |k, mut s| {
        esp32_head(&mut s).ok();
        let f = jpeg(64, 48, 20, 20);
        match k {
            0 => {
                esp32_part(&mut s, &f, 1_000_000).ok();
                // Stall longer than the read timeout (0.5 s).
                std::thread::sleep(Duration::from_millis(1500));
            }
            1 => {
                esp32_part(&mut s, &f, 2_000_000).ok();
                // Half a frame, then the connection drops.
                let head = format!(
                    "\r\n--{}\r\nContent-Type: image/jpeg\r\nContent-Length: {}\r\n\r\n",
                    live_server::ESP32_BOUNDARY,
                    f.len()
                );
                live_server::chunk(&mut s, head.as_bytes()).ok();
                let _ = write!(s, "{:X}\r\n", f.len());
                let _ = s.write_all(&f[..f.len() / 2]);
            }
            _ => {
                esp32_part(&mut s, &f, 3_000_000).ok();
                esp32_part(&mut s, &f, 3_100_000).ok();
                std::thread::sleep(Duration::from_millis(300));
            }
        }
    });
    let r = Reader::start(config(&url), Arc::new(AtomicBool::new(false)), None).unwrap();
    let got = collect(&r, 4, 15.0);
    let c = r.latest.counters.snapshot();
    assert_eq!(c.received, 4, "{c:?}");
    assert_eq!(c.reconnects, 2, "{c:?}");
    assert!((got.last().unwrap().camera_s.unwrap() - 3.1).abs() < 1e-9);
    r.stop();
    h.join().unwrap();
}

#[test]
fn a_camera_that_never_answers_times_out_with_a_clear_message() {
    let (url, h) = server(1, |_, mut s| {
        read_request(&mut s);
        std::thread::sleep(Duration::from_millis(1500));
    });
    let t = Instant::now();
    let e = Reader::start(config(&url), Arc::new(AtomicBool::new(false)), None)
        .err()
        .expect("no answer is an error")
        .to_string();
    assert!(e.contains("no answer within 0.5 s"), "{e}");
    assert!(t.elapsed() < Duration::from_secs(3));
    h.join().unwrap();
}

#[test]
fn refused_answers_are_named() {
    let (url, h) = server(2, |k, mut s| {
        read_request(&mut s);
        let _ = if k == 0 {
            s.write_all(b"HTTP/1.1 404 Not Found\r\nContent-Length: 0\r\n\r\n")
        } else {
            s.write_all(
                b"HTTP/1.1 200 OK\r\nContent-Type: text/html\r\nContent-Length: 2\r\n\r\nhi",
            )
        };
    });
    let e1 = Reader::start(config(&url), Arc::new(AtomicBool::new(false)), None)
        .err()
        .unwrap()
        .to_string();
    assert!(
        e1.contains("answered HTTP 404 Not Found, expected 200"),
        "{e1}"
    );
    let e2 = Reader::start(config(&url), Arc::new(AtomicBool::new(false)), None)
        .err()
        .unwrap()
        .to_string();
    assert!(e2.contains("not an MJPEG stream"), "{e2}");
    h.join().unwrap();
}

#[test]
fn boundary_frame_without_lengths_an_absurd_length_and_a_size_change() {
    let (url, h) = server(1, |_, mut s| {
        read_request(&mut s);
        // Another firmware: quoted boundary, not chunked, no Content-Length, no leading CRLF,
        // header names in other cases.
        let _ = s.write_all(
            b"HTTP/1.0 200 OK\r\ncontent-type: multipart/x-mixed-replace; boundary=\"frame\"\r\n\r\n",
        );
        let small = jpeg(64, 48, 20, 20);
        let big = jpeg(96, 72, 30, 30);
        let _ = s.write_all(b"--frame\r\ncontent-type: image/jpeg\r\n\r\n");
        let _ = s.write_all(&small);
        let _ = s.write_all(b"\r\n--frame\r\nCONTENT-LENGTH: 99999999999\r\n\r\n");
        let _ = s.write_all(&small);
        let _ = s.write_all(b"\r\n--frame\r\nContent-Type: image/jpeg\r\n\r\n");
        let _ = s.write_all(&big);
        let _ = s.write_all(b"\r\n--frame\r\n\r\n");
        let _ = s.flush();
        std::thread::sleep(Duration::from_millis(300));
    });
    let r = Reader::start(config(&url), Arc::new(AtomicBool::new(false)), None).unwrap();
    let got = collect(&r, 3, 10.0);
    let c = r.latest.counters.snapshot();
    assert_eq!((c.received, c.bad), (3, 0), "{c:?}");
    assert_eq!(got.last().unwrap().image.shape(), (3, 72, 96));
    assert!(got.last().unwrap().camera_s.is_none());
    r.stop();
    h.join().unwrap();
}

#[test]
fn the_slot_keeps_only_the_latest_frame_and_counts_drops() {
    let (url, h) = server(1, |_, mut s| {
        esp32_head(&mut s).ok();
        for k in 0..6u64 {
            esp32_part(&mut s, &jpeg(32, 24, 10, 10), 100 + k).ok();
        }
        std::thread::sleep(Duration::from_millis(500));
    });
    let r = Reader::start(config(&url), Arc::new(AtomicBool::new(false)), None).unwrap();
    // Nobody takes frames for a while: all but the last are dropped, none queued.
    let end = Instant::now() + Duration::from_secs(10);
    while r.latest.counters.snapshot().received < 6 && Instant::now() < end {
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(100));
    let f = r.latest.take(Duration::from_millis(100)).expect("a frame");
    let c = r.latest.counters.snapshot();
    assert_eq!((c.received, c.dropped), (6, 5), "{c:?}");
    assert_eq!(f.seq, 5);
    assert!(r.latest.take(Duration::from_millis(50)).is_none());
    r.stop();
    h.join().unwrap();
}
