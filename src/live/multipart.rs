//! `multipart/x-mixed-replace`, the MJPEG stream: the boundary from the Content-Type header
//! (quoted or not), then parts `[CRLF] --BOUNDARY CRLF headers CRLF CRLF body`, each body read by
//! its Content-Length when it has a sane one, otherwise up to the next boundary.

use std::io::{self, Read};

use super::input::Input;

/// The boundary of a `multipart/*` Content-Type, or why there is none.
pub fn boundary_of(content_type: &str) -> Result<String, String> {
    let mut params = content_type.split(';');
    let mime = params.next().unwrap_or("").trim().to_ascii_lowercase();
    if !mime.starts_with("multipart/") {
        return Err(format!(
            "not an MJPEG stream: Content-Type {content_type:?}, expected multipart/x-mixed-replace"
        ));
    }
    for p in params {
        if let Some((k, v)) = p.split_once('=')
            && k.trim().eq_ignore_ascii_case("boundary")
        {
            let v = v.trim();
            let v = v
                .strip_prefix('"')
                .and_then(|v| v.strip_suffix('"'))
                .unwrap_or(v);
            if v.is_empty() || v.len() > 200 {
                return Err(format!("bad boundary in Content-Type {content_type:?}"));
            }
            return Ok(v.to_string());
        }
    }
    Err(format!("no boundary in Content-Type {content_type:?}"))
}

/// Caps on what one part may hold.
#[derive(Clone, Copy, Debug)]
pub struct Caps {
    /// Largest part body (bytes).
    pub part: usize,
    /// Bytes of junk skipped while looking for the next boundary.
    pub skip: usize,
}

impl Default for Caps {
    fn default() -> Self {
        Self {
            part: 16 << 20,
            skip: 16 << 20,
        }
    }
}

/// One part of the stream.
#[derive(Clone, Debug)]
pub struct Part {
    pub body: Vec<u8>,
    /// Part headers, names lower-cased.
    pub headers: Vec<(String, String)>,
    /// The Content-Length it declared, when it had one.
    pub declared_length: Option<u64>,
}

impl Part {
    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_str())
    }
}

/// Parts read off a body stream.
pub struct Parts<R> {
    input: Input<R>,
    boundary: Vec<u8>,
    caps: Caps,
}

const MAX_PART_HEADER_LINE: usize = 4096;
const MAX_PART_HEADERS: usize = 32;

impl<R: Read> Parts<R> {
    pub fn new(input: Input<R>, boundary: &str, caps: Caps) -> Self {
        Self {
            input,
            boundary: boundary.as_bytes().to_vec(),
            caps,
        }
    }

    /// Whether `line` is this stream's boundary line; `Some(true)` for the closing one.
    fn is_boundary(&self, line: &[u8]) -> Option<bool> {
        let line = trim_end(line);
        let b = &self.boundary[..];
        // The usual `--B`; some servers put the dashes in the parameter already.
        let rest = line
            .strip_prefix(b"--")
            .and_then(|r| r.strip_prefix(b))
            .or_else(|| line.strip_prefix(b).filter(|_| b.starts_with(b"--")))?;
        match rest {
            b"" => Some(false),
            b"--" => Some(true),
            _ => None,
        }
    }

    /// The next part; `Ok(None)` at the closing boundary or a clean end of the stream.
    pub fn next_part(&mut self) -> io::Result<Option<Part>> {
        // Skip to the boundary line (a leading CRLF, or junk after a part's declared length).
        let mut skipped = 0usize;
        loop {
            let Some(line) = self.input.read_line(self.caps.skip.max(1024))? else {
                return Ok(None);
            };
            match self.is_boundary(&line) {
                Some(true) => return Ok(None),
                Some(false) => break,
                None => {
                    skipped += line.len() + 1;
                    if skipped > self.caps.skip {
                        return Err(bad(format!("no boundary line in {skipped} bytes")));
                    }
                }
            }
        }
        let mut headers = Vec::new();
        loop {
            let line = self
                .input
                .read_line(MAX_PART_HEADER_LINE)?
                .ok_or_else(|| eof("inside part headers"))?;
            if line.is_empty() {
                break;
            }
            if headers.len() >= MAX_PART_HEADERS {
                return Err(bad(format!("more than {MAX_PART_HEADERS} part headers")));
            }
            let text = String::from_utf8_lossy(&line);
            if let Some((n, v)) = text.split_once(':') {
                headers.push((n.trim().to_ascii_lowercase(), v.trim().to_string()));
            }
        }
        let declared = headers
            .iter()
            .find(|(n, _)| n == "content-length")
            .and_then(|(_, v)| v.parse::<u64>().ok());
        let body = match declared {
            Some(n) if n <= self.caps.part as u64 => self.input.read_exact_vec(n as usize)?,
            // No length, or an absurd one: the body ends where the next boundary starts.
            _ => {
                let mut delim = b"\r\n--".to_vec();
                delim.extend_from_slice(&self.boundary);
                let mut body = self.input.read_until(&delim, self.caps.part)?;
                if body.len() > self.caps.part {
                    body.clear();
                }
                body
            }
        };
        Ok(Some(Part {
            body,
            headers,
            declared_length: declared,
        }))
    }
}

fn trim_end(mut s: &[u8]) -> &[u8] {
    while let Some((&l, rest)) = s.split_last() {
        if l == b' ' || l == b'\t' || l == b'\r' {
            s = rest;
        } else {
            break;
        }
    }
    s
}

fn bad(msg: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidData, msg)
}

fn eof(where_: &str) -> io::Error {
    io::Error::new(
        io::ErrorKind::UnexpectedEof,
        format!("the connection closed {where_}"),
    )
}

/// X-Timestamp `S.USEC` in seconds. The firmware prints `%ld.%06ld`; some versions drop the
/// zero padding (`12.5` for 12 s + 5 µs), so the digits after the dot are read as a whole
/// number of microseconds, never as a decimal fraction.
pub fn parse_timestamp(v: &str) -> Option<f64> {
    let v = v.trim();
    let (s, us) = v.split_once('.').unwrap_or((v, "0"));
    let s: u64 = s.parse().ok()?;
    let us: u64 = if us.is_empty() { 0 } else { us.parse().ok()? };
    if us >= 1_000_000 {
        return None;
    }
    Some(s as f64 + us as f64 * 1e-6)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn boundaries_quoted_or_not_and_refusals() {
        assert_eq!(
            boundary_of("multipart/x-mixed-replace;boundary=123456789000000000000987654321")
                .unwrap(),
            "123456789000000000000987654321"
        );
        assert_eq!(
            boundary_of("Multipart/X-Mixed-Replace; Boundary=\"frame\"").unwrap(),
            "frame"
        );
        assert!(boundary_of("text/html").is_err());
        assert!(boundary_of("multipart/x-mixed-replace").is_err());
    }

    #[test]
    fn timestamps_are_seconds_and_microseconds() {
        assert_eq!(parse_timestamp("12.000005"), Some(12.000005));
        assert_eq!(parse_timestamp("12.5"), Some(12.000005));
        assert_eq!(parse_timestamp("7"), Some(7.0));
        assert_eq!(parse_timestamp("x"), None);
        assert_eq!(parse_timestamp("1.9999999"), None);
    }

    #[test]
    fn parts_with_and_without_length_and_leading_crlf() {
        let wire: &[u8] = b"--b\r\ncontent-type: image/jpeg\r\nContent-Length: 3\r\n\r\nabc\
            \r\n--b\r\nX-Timestamp: 1.5\r\n\r\nxyz\r\n--b\r\nContent-Length: 99999999999\r\n\r\nq\r\n--b--\r\n";
        let mut p = Parts::new(
            Input::new(wire),
            "b",
            Caps {
                part: 1000,
                skip: 1000,
            },
        );
        let a = p.next_part().unwrap().unwrap();
        assert_eq!(a.body, b"abc");
        assert_eq!(a.header("content-type"), Some("image/jpeg"));
        let b = p.next_part().unwrap().unwrap();
        assert_eq!(
            (b.body.as_slice(), b.header("x-timestamp")),
            (&b"xyz"[..], Some("1.5"))
        );
        let c = p.next_part().unwrap().unwrap();
        assert_eq!(c.body, b"q");
        assert!(p.next_part().unwrap().is_none());
    }
}
