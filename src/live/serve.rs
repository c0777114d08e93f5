//! The browser view's HTTP server: `/` the page, `/stream.mjpg` an MJPEG re-stream of the view
//! frames, `/stats.json` the latest figures, `/events` the same as server-sent events. One
//! thread per client, at most `MAX_CLIENTS` at once; every wait wakes to see the stop flag.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use crate::error::{Error, Result};

const PAGE: &str = include_str!("page.html");
const MAX_CLIENTS: usize = 16;
const BOUNDARY: &str = "pinsliveframe";

/// What the pipeline publishes for the view.
#[derive(Default)]
pub struct ViewState {
    snap: Mutex<Snapshot>,
    changed: Condvar,
    pub stop: AtomicBool,
}

#[derive(Clone, Default)]
struct Snapshot {
    version: u64,
    jpeg: Option<Arc<Vec<u8>>>,
    json: Option<Arc<String>>,
}

impl ViewState {
    /// Publishes a new view frame (when given) and figures.
    pub fn publish(&self, jpeg: Option<Vec<u8>>, json: String) {
        if let Ok(mut s) = self.snap.lock() {
            s.version += 1;
            if let Some(j) = jpeg {
                s.jpeg = Some(Arc::new(j));
            }
            s.json = Some(Arc::new(json));
            self.changed.notify_all();
        }
    }

    /// Ends every client's wait.
    pub fn shut(&self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Ok(_s) = self.snap.lock() {
            self.changed.notify_all();
        }
    }

    /// The first snapshot newer than `version`, waiting up to a second.
    fn newer(&self, version: u64) -> Option<Snapshot> {
        let s = self.snap.lock().ok()?;
        let (s, _) = self
            .changed
            .wait_timeout_while(s, Duration::from_secs(1), |s| {
                s.version <= version && !self.stop.load(Ordering::Relaxed)
            })
            .ok()?;
        (s.version > version).then(|| s.clone())
    }
}

/// Binds `addr` and serves on a thread; returns the bound address.
pub fn serve(addr: &str, state: Arc<ViewState>) -> Result<(SocketAddr, JoinHandle<()>)> {
    let listener = TcpListener::bind(addr)
        .map_err(|e| Error::invalid(format!("--serve {addr}"), e.to_string()))?;
    let local = listener
        .local_addr()
        .map_err(|e| Error::invalid(format!("--serve {addr}"), e.to_string()))?;
    listener
        .set_nonblocking(true)
        .map_err(|e| Error::invalid(format!("--serve {addr}"), e.to_string()))?;
    let clients = Arc::new(AtomicUsize::new(0));
    let handle = std::thread::Builder::new()
        .name("pins-live-serve".into())
        .spawn(move || {
            while !state.stop.load(Ordering::Relaxed) {
                match listener.accept() {
                    Ok((stream, _)) => {
                        if clients.load(Ordering::Relaxed) >= MAX_CLIENTS {
                            let _ =
                                respond(&stream, "503 Service Unavailable", "text/plain", b"busy");
                            continue;
                        }
                        clients.fetch_add(1, Ordering::Relaxed);
                        let (st, cl) = (state.clone(), clients.clone());
                        let spawned = std::thread::Builder::new()
                            .name("pins-live-client".into())
                            .spawn(move || {
                                let _ = client(stream, &st);
                                cl.fetch_sub(1, Ordering::Relaxed);
                            });
                        if spawned.is_err() {
                            clients.fetch_sub(1, Ordering::Relaxed);
                        }
                    }
                    Err(_) => std::thread::sleep(Duration::from_millis(50)),
                }
            }
        })
        .map_err(|e| Error::invalid("view server thread", e.to_string()))?;
    Ok((local, handle))
}

fn respond(mut s: &TcpStream, status: &str, ctype: &str, body: &[u8]) -> std::io::Result<()> {
    write!(
        s,
        "HTTP/1.1 {status}\r\nContent-Type: {ctype}\r\nContent-Length: {}\r\nCache-Control: no-store\r\nConnection: close\r\n\r\n",
        body.len()
    )?;
    s.write_all(body)
}

fn client(stream: TcpStream, state: &ViewState) -> std::io::Result<()> {
    stream.set_nonblocking(false)?;
    stream.set_read_timeout(Some(Duration::from_secs(5)))?;
    stream.set_write_timeout(Some(Duration::from_secs(5)))?;
    let mut reader = BufReader::new(stream.try_clone()?);
    let mut request = String::new();
    reader.by_ref().take(8192).read_line(&mut request)?;
    // Headers up to the blank line (bounded).
    for _ in 0..100 {
        let mut l = String::new();
        if reader.by_ref().take(8192).read_line(&mut l)? == 0 || l.trim().is_empty() {
            break;
        }
    }
    let path = request.split_whitespace().nth(1).unwrap_or("/");
    let path = path.split('?').next().unwrap_or("/");
    let mut s = &stream;
    match path {
        "/" | "/index.html" => respond(s, "200 OK", "text/html; charset=utf-8", PAGE.as_bytes()),
        "/stats.json" => {
            let snap = state.snap.lock().map(|s| s.clone()).unwrap_or_default();
            match snap.json {
                Some(j) => respond(s, "200 OK", "application/json", j.as_bytes()),
                None => respond(s, "503 Service Unavailable", "application/json", b"{}"),
            }
        }
        "/stream.mjpg" => {
            write!(
                s,
                "HTTP/1.1 200 OK\r\nContent-Type: multipart/x-mixed-replace;boundary={BOUNDARY}\r\nCache-Control: no-store\r\nConnection: close\r\n\r\n"
            )?;
            let mut version = 0;
            let mut sent: Option<Arc<Vec<u8>>> = None;
            while !state.stop.load(Ordering::Relaxed) {
                let Some(snap) = state.newer(version) else {
                    continue;
                };
                version = snap.version;
                if let Some(j) = snap.jpeg
                    && sent.as_ref().is_none_or(|p| !Arc::ptr_eq(p, &j))
                {
                    write!(
                        s,
                        "\r\n--{BOUNDARY}\r\nContent-Type: image/jpeg\r\nContent-Length: {}\r\n\r\n",
                        j.len()
                    )?;
                    s.write_all(&j)?;
                    s.flush()?;
                    sent = Some(j);
                }
            }
            Ok(())
        }
        "/events" => {
            write!(
                s,
                "HTTP/1.1 200 OK\r\nContent-Type: text/event-stream\r\nCache-Control: no-store\r\nConnection: close\r\n\r\n"
            )?;
            let mut version = 0;
            while !state.stop.load(Ordering::Relaxed) {
                match state.newer(version) {
                    Some(snap) => {
                        version = snap.version;
                        if let Some(j) = snap.json {
                            write!(s, "data: {j}\n\n")?;
                        }
                    }
                    // A comment keeps the connection alive and finds a closed client.
                    None => write!(s, ": idle\n\n")?,
                }
                s.flush()?;
            }
            Ok(())
        }
        _ => respond(s, "404 Not Found", "text/plain", b"not found"),
    }
}
