//! A TCP stream whose reads give up after a stall (no byte for `stall`) or when the stop flag
//! is raised; the socket itself wakes every `TICK` to look at both.

use std::io::{self, Read};
use std::net::TcpStream;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// How often a blocked read wakes to check the stop flag and its deadline.
pub const TICK: Duration = Duration::from_millis(100);

/// A reading half of a connection with a stall deadline.
pub struct Socket {
    stream: TcpStream,
    stall: Duration,
    stop: Arc<AtomicBool>,
}

impl Socket {
    /// Wraps a connected stream: a read fails with `TimedOut` when no byte came for `stall`,
    /// and with `Interrupted`-like `Other` ("stopped") once `stop` is set.
    pub fn new(stream: TcpStream, stall: Duration, stop: Arc<AtomicBool>) -> io::Result<Self> {
        stream.set_read_timeout(Some(TICK.min(stall).max(Duration::from_millis(1))))?;
        Ok(Self {
            stream,
            stall,
            stop,
        })
    }

    /// Changes the stall deadline (the response timeout for the head, then the read timeout).
    pub fn set_stall(&mut self, stall: Duration) -> io::Result<()> {
        self.stall = stall;
        self.stream
            .set_read_timeout(Some(TICK.min(stall).max(Duration::from_millis(1))))
    }
}

/// The error a read returns once the stop flag is set.
pub fn stopped() -> io::Error {
    io::Error::other("stopped")
}

/// True for the error [`stopped`] makes.
pub fn is_stopped(e: &io::Error) -> bool {
    e.kind() == io::ErrorKind::Other && e.to_string() == "stopped"
}

impl Read for Socket {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let started = Instant::now();
        loop {
            if self.stop.load(Ordering::Relaxed) {
                return Err(stopped());
            }
            match self.stream.read(buf) {
                Ok(n) => return Ok(n),
                Err(e)
                    if matches!(
                        e.kind(),
                        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                    ) =>
                {
                    if started.elapsed() >= self.stall {
                        return Err(io::Error::new(
                            io::ErrorKind::TimedOut,
                            format!("no data for {:.1} s", self.stall.as_secs_f64()),
                        ));
                    }
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
    }
}
