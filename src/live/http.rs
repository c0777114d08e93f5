//! One HTTP/1.1 GET over a plain TCP stream: connect with a timeout, send the request, read the
//! status line and headers within the response timeout, and hand back the body as a reader
//! (chunked transfer decoded) whose every read is bounded by the read timeout.

use std::io::{self, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use super::chunked::ChunkedReader;
use super::input::Input;
use super::socket::Socket;
use super::url::HttpUrl;
use crate::error::{Error, Result};

/// Timeouts and caps of a request.
#[derive(Clone, Debug)]
pub struct Timeouts {
    /// TCP connect.
    pub connect: Duration,
    /// From the request to the end of the response headers (a busy ESP32 accepts a second
    /// client and never answers it).
    pub response: Duration,
    /// Longest wait for any byte of the body (a stalled stream).
    pub read: Duration,
}

impl Default for Timeouts {
    fn default() -> Self {
        Self {
            connect: Duration::from_secs(5),
            response: Duration::from_secs(5),
            read: Duration::from_secs(5),
        }
    }
}

/// Longest status or header line, and most header lines.
const MAX_HEADER_LINE: usize = 8192;
const MAX_HEADERS: usize = 100;

/// A response: status, headers (names lower-cased) and the body.
pub struct Response {
    pub status: u16,
    pub reason: String,
    pub headers: Vec<(String, String)>,
    pub body: Input<Box<dyn Read + Send>>,
}

impl Response {
    /// The first header named `name` (lower case).
    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_str())
    }
}

/// Sends `GET url` and reads the response head.
pub fn get(url: &HttpUrl, t: &Timeouts, stop: Arc<AtomicBool>) -> Result<Response> {
    let what = || format!("camera {url}");
    let net = |e: io::Error| Error::invalid(what(), e.to_string());
    let addrs: Vec<_> = url
        .authority()
        .to_socket_addrs()
        .map_err(|e| Error::invalid(what(), format!("cannot resolve the host: {e}")))?
        .collect();
    let mut last = None;
    let mut stream = None;
    for a in &addrs {
        match TcpStream::connect_timeout(a, t.connect) {
            Ok(s) => {
                stream = Some(s);
                break;
            }
            Err(e) => last = Some(e),
        }
    }
    let stream = stream.ok_or_else(|| {
        Error::invalid(
            what(),
            format!(
                "cannot connect within {:.1} s: {}",
                t.connect.as_secs_f64(),
                last.map_or("no address".to_string(), |e| e.to_string())
            ),
        )
    })?;
    stream.set_nodelay(true).map_err(net)?;
    stream.set_write_timeout(Some(t.response)).map_err(net)?;
    let request = format!(
        "GET {} HTTP/1.1\r\nHost: {}\r\nUser-Agent: pins-live\r\nAccept: */*\r\nConnection: close\r\n\r\n",
        url.path,
        url.authority()
    );
    (&stream).write_all(request.as_bytes()).map_err(net)?;
    let socket = Socket::new(stream, t.response, stop).map_err(net)?;
    let mut input = Input::new(socket);
    let head_err = |e: io::Error| {
        if e.kind() == io::ErrorKind::TimedOut {
            Error::invalid(
                what(),
                format!(
                    "no answer within {:.1} s (the ESP32 serves one client at a time: is another \
                     one connected?)",
                    t.response.as_secs_f64()
                ),
            )
        } else {
            Error::invalid(what(), format!("reading the response: {e}"))
        }
    };
    let status_line = input
        .read_line(MAX_HEADER_LINE)
        .map_err(head_err)?
        .ok_or_else(|| Error::invalid(what(), "the connection closed without an answer"))?;
    let status_text = String::from_utf8_lossy(&status_line).to_string();
    let mut words = status_text.splitn(3, ' ');
    let proto = words.next().unwrap_or("");
    let status = words.next().and_then(|s| s.parse::<u16>().ok());
    let (Some(status), true) = (status, proto.starts_with("HTTP/1.")) else {
        return Err(Error::invalid(
            what(),
            format!("not an HTTP/1.x answer: {status_text:?}"),
        ));
    };
    let reason = words.next().unwrap_or("").trim().to_string();
    let mut headers = Vec::new();
    loop {
        let line = input
            .read_line(MAX_HEADER_LINE)
            .map_err(head_err)?
            .ok_or_else(|| Error::invalid(what(), "the connection closed inside the headers"))?;
        if line.is_empty() {
            break;
        }
        if headers.len() >= MAX_HEADERS {
            return Err(Error::invalid(
                what(),
                format!("more than {MAX_HEADERS} header lines"),
            ));
        }
        let text = String::from_utf8_lossy(&line);
        if let Some((n, v)) = text.split_once(':') {
            headers.push((n.trim().to_ascii_lowercase(), v.trim().to_string()));
        }
    }
    input.get_mut().set_stall(t.read).map_err(net)?;
    let chunked = headers
        .iter()
        .any(|(n, v)| n == "transfer-encoding" && v.to_ascii_lowercase().contains("chunked"));
    let body: Box<dyn Read + Send> = if chunked {
        Box::new(ChunkedReader::new(input))
    } else {
        Box::new(InputReader(input))
    };
    Ok(Response {
        status,
        reason,
        headers,
        body: Input::new(body),
    })
}

/// An [`Input`] (with bytes already buffered) as a plain reader.
struct InputReader<R>(Input<R>);

impl<R: Read> Read for InputReader<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let data = self.0.read_some(buf.len())?;
        buf[..data.len()].copy_from_slice(&data);
        Ok(data.len())
    }
}

/// `GET url` expecting 200 and a small body (the camera's `/control` and `/status`).
pub fn get_small(url: &HttpUrl, t: &Timeouts, cap: usize) -> Result<Vec<u8>> {
    let mut r = get(url, t, Arc::new(AtomicBool::new(false)))?;
    if r.status != 200 {
        return Err(Error::invalid(
            format!("camera {url}"),
            format!("answered HTTP {} {}, expected 200", r.status, r.reason),
        ));
    }
    let mut out = Vec::new();
    loop {
        let d = r
            .body
            .read_some(64 * 1024)
            .map_err(|e| Error::invalid(format!("camera {url}"), e.to_string()))?;
        if d.is_empty() {
            break;
        }
        out.extend_from_slice(&d);
        if out.len() > cap {
            return Err(Error::invalid(
                format!("camera {url}"),
                format!("an answer longer than {cap} bytes"),
            ));
        }
        if let Some(n) = r
            .header("content-length")
            .and_then(|v| v.parse::<usize>().ok())
            && out.len() >= n
        {
            out.truncate(n);
            break;
        }
    }
    Ok(out)
}
