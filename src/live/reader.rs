//! The reader thread: reads parts off the camera's stream, keeps only whole JPEGs, and leaves the
//! latest one in a one-frame slot (a frame replaced before it was taken counts as dropped;
//! nothing queues). Any failure after the first connection (a stall, a closed connection, a
//! bad answer) is followed by a reconnection with exponential backoff.

use std::io::Read;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::http::{Timeouts, get};
use super::jpeg::decode_frame;
use super::multipart::{Caps, Parts, boundary_of, parse_timestamp};
use super::socket::is_stopped;
use super::url::HttpUrl;
use crate::error::{Error, Result};
use crate::types::Image;

/// One whole, decoded frame.
#[derive(Clone, Debug)]
pub struct Frame {
    /// Order of arrival among the whole frames (0, 1, …).
    pub seq: u64,
    pub jpeg: Arc<Vec<u8>>,
    pub image: Arc<Image>,
    /// The camera's X-Timestamp (seconds since its boot), when it sent one.
    pub camera_s: Option<f64>,
    /// Seconds since the reader started, when the frame was complete.
    pub received_s: f64,
    /// When it was complete (for the latency; the time it was read back, in a replay).
    pub arrived: Instant,
}

/// What the reader has seen.
#[derive(Debug, Default)]
pub struct Counters {
    /// Whole frames received.
    pub received: AtomicU64,
    /// Whole frames replaced in the slot before the pipeline took them.
    pub dropped: AtomicU64,
    /// Parts skipped: truncated, corrupt or oversized JPEGs.
    pub bad: AtomicU64,
    /// Connections made after the first.
    pub reconnects: AtomicU64,
}

/// A snapshot of [`Counters`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Counts {
    pub received: u64,
    pub dropped: u64,
    pub bad: u64,
    pub reconnects: u64,
}

impl Counters {
    pub fn snapshot(&self) -> Counts {
        Counts {
            received: self.received.load(Ordering::Relaxed),
            dropped: self.dropped.load(Ordering::Relaxed),
            bad: self.bad.load(Ordering::Relaxed),
            reconnects: self.reconnects.load(Ordering::Relaxed),
        }
    }
}

/// The one-frame slot between the reader and the pipeline.
#[derive(Default)]
pub struct Latest {
    slot: Mutex<Option<Frame>>,
    ready: Condvar,
    pub counters: Counters,
    /// Set when the reader thread has ended (stopped, or out of reconnections).
    pub ended: AtomicBool,
    /// The last problem, for the log and the browser view.
    pub last_error: Mutex<Option<String>>,
}

impl Latest {
    /// Puts a frame, replacing (and counting as dropped) any frame not yet taken.
    pub fn put(&self, frame: Frame) {
        self.counters.received.fetch_add(1, Ordering::Relaxed);
        if let Ok(mut s) = self.slot.lock() {
            if s.replace(frame).is_some() {
                self.counters.dropped.fetch_add(1, Ordering::Relaxed);
            }
            self.ready.notify_all();
        }
    }

    /// Takes the latest frame, waiting up to `timeout` for one.
    pub fn take(&self, timeout: Duration) -> Option<Frame> {
        let guard = self.slot.lock().ok()?;
        let (mut guard, _) = self
            .ready
            .wait_timeout_while(guard, timeout, |s| {
                s.is_none() && !self.ended.load(Ordering::Relaxed)
            })
            .ok()?;
        guard.take()
    }

    fn note(&self, msg: String, quiet: bool) {
        if !quiet {
            eprintln!("live: {msg}");
        }
        if let Ok(mut e) = self.last_error.lock() {
            *e = Some(msg);
        }
    }
}

/// How to read the stream.
#[derive(Clone, Debug)]
pub struct ReaderConfig {
    pub url: HttpUrl,
    pub timeouts: Timeouts,
    pub caps: Caps,
    /// First and longest wait before a reconnection.
    pub backoff_min: Duration,
    pub backoff_max: Duration,
    /// Give up after this many failed reconnections in a row (`None`: never).
    pub max_failures: Option<usize>,
    /// No log lines on stderr.
    pub quiet: bool,
}

impl ReaderConfig {
    pub fn new(url: HttpUrl) -> Self {
        Self {
            url,
            timeouts: Timeouts::default(),
            caps: Caps::default(),
            backoff_min: Duration::from_millis(250),
            backoff_max: Duration::from_secs(5),
            max_failures: None,
            quiet: false,
        }
    }
}

/// Called on the reader thread with every whole frame before it is offered (the recorder).
pub type FrameHook = Box<dyn FnMut(&Frame) -> Result<()> + Send>;

type Body = Box<dyn Read + Send>;

/// Connects and checks the answer: 200 and a multipart Content-Type with a boundary.
pub fn open(cfg: &ReaderConfig, stop: Arc<AtomicBool>) -> Result<Parts<Body>> {
    let r = get(&cfg.url, &cfg.timeouts, stop)?;
    let what = || format!("camera {}", cfg.url);
    if r.status != 200 {
        return Err(Error::invalid(
            what(),
            format!("answered HTTP {} {}, expected 200", r.status, r.reason),
        ));
    }
    let ct = r.header("content-type").unwrap_or("(none)").to_string();
    let boundary = boundary_of(&ct).map_err(|e| Error::invalid(what(), e))?;
    Ok(Parts::new(r.body, &boundary, cfg.caps))
}

/// The running reader.
pub struct Reader {
    pub latest: Arc<Latest>,
    stop: Arc<AtomicBool>,
    handle: Option<JoinHandle<()>>,
}

impl Reader {
    /// Makes the first connection here (its failure is the caller's error), then reads on a
    /// thread. `stop` ends the thread; `hook` sees every whole frame (an error from it stops
    /// the reader and is kept in `last_error`).
    pub fn start(
        cfg: ReaderConfig,
        stop: Arc<AtomicBool>,
        hook: Option<FrameHook>,
    ) -> Result<Self> {
        let first = open(&cfg, stop.clone())?;
        let latest = Arc::new(Latest::default());
        let (l, s) = (latest.clone(), stop.clone());
        let handle = std::thread::Builder::new()
            .name("pins-live-reader".into())
            .spawn(move || {
                run(cfg, first, &l, s, hook);
                l.ended.store(true, Ordering::Relaxed);
                if let Ok(_g) = l.slot.lock() {
                    l.ready.notify_all();
                }
            })
            .map_err(|e| Error::invalid("reader thread", e.to_string()))?;
        Ok(Self {
            latest,
            stop,
            handle: Some(handle),
        })
    }

    /// Stops the thread and waits for it (a read wakes within [`super::socket::TICK`]).
    pub fn stop(mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }
}

impl Drop for Reader {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }
}

fn run(
    cfg: ReaderConfig,
    first: Parts<Body>,
    latest: &Latest,
    stop: Arc<AtomicBool>,
    mut hook: Option<FrameHook>,
) {
    let started = Instant::now();
    let mut parts = Some(first);
    let mut backoff = cfg.backoff_min;
    let mut failures = 0usize;
    let mut seq = 0u64;
    while !stop.load(Ordering::Relaxed) {
        let Some(p) = parts.as_mut() else {
            // Reconnect after a pause that doubles with every failure in a row.
            if !sleep_unless(&stop, backoff) {
                break;
            }
            backoff = (backoff * 2).min(cfg.backoff_max);
            match open(&cfg, stop.clone()) {
                Ok(p) => {
                    latest.counters.reconnects.fetch_add(1, Ordering::Relaxed);
                    parts = Some(p);
                }
                Err(e) => {
                    failures += 1;
                    latest.note(format!("reconnecting: {e}"), cfg.quiet);
                    if cfg.max_failures.is_some_and(|m| failures > m) {
                        latest.note(
                            format!("giving up after {failures} failed reconnections"),
                            cfg.quiet,
                        );
                        break;
                    }
                }
            }
            continue;
        };
        match p.next_part() {
            Ok(Some(part)) => match decode_frame(&part.body) {
                Ok(image) => {
                    let camera_s = part.header("x-timestamp").and_then(parse_timestamp);
                    let frame = Frame {
                        seq,
                        jpeg: Arc::new(part.body),
                        image: Arc::new(image),
                        camera_s,
                        received_s: started.elapsed().as_secs_f64(),
                        arrived: Instant::now(),
                    };
                    seq += 1;
                    backoff = cfg.backoff_min;
                    failures = 0;
                    if let Some(h) = hook.as_mut()
                        && let Err(e) = h(&frame)
                    {
                        latest.note(format!("stopping: {e}"), cfg.quiet);
                        break;
                    }
                    latest.put(frame);
                }
                Err(bad) => {
                    latest.counters.bad.fetch_add(1, Ordering::Relaxed);
                    latest.note(format!("skipped a frame: {bad}"), cfg.quiet);
                }
            },
            Ok(None) => {
                latest.note("the stream ended; reconnecting".into(), cfg.quiet);
                parts = None;
            }
            Err(e) if is_stopped(&e) => break,
            Err(e) => {
                // A part cut short by the drop is lost with the connection.
                latest.note(format!("stream error: {e}; reconnecting"), cfg.quiet);
                parts = None;
            }
        }
    }
}

/// Sleeps `d` in short steps; false when `stop` was raised.
fn sleep_unless(stop: &AtomicBool, d: Duration) -> bool {
    let end = Instant::now() + d;
    while Instant::now() < end {
        if stop.load(Ordering::Relaxed) {
            return false;
        }
        std::thread::sleep(Duration::from_millis(20).min(end - Instant::now()));
    }
    !stop.load(Ordering::Relaxed)
}
