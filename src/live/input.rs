//! A byte buffer over any reader with the three reads a multipart stream needs: a line (capped),
//! exactly N bytes, and everything up to a delimiter (capped), leaving what follows unread.

use std::io::{self, Read};

/// Buffered input that can look ahead.
pub struct Input<R> {
    inner: R,
    buf: Vec<u8>,
    pos: usize,
    /// Bytes consumed so far.
    pub consumed: u64,
}

const READ_SIZE: usize = 64 * 1024;

impl<R: Read> Input<R> {
    pub fn new(inner: R) -> Self {
        Self {
            inner,
            buf: Vec::new(),
            pos: 0,
            consumed: 0,
        }
    }

    /// The reader underneath.
    pub fn get_mut(&mut self) -> &mut R {
        &mut self.inner
    }

    fn available(&self) -> &[u8] {
        &self.buf[self.pos..]
    }

    /// Reads more bytes into the buffer; `Ok(0)` at the end of the input.
    fn fill(&mut self) -> io::Result<usize> {
        if self.pos > 0 && self.pos == self.buf.len() {
            self.buf.clear();
            self.pos = 0;
        } else if self.pos > READ_SIZE {
            self.buf.drain(..self.pos);
            self.pos = 0;
        }
        let old = self.buf.len();
        self.buf.resize(old + READ_SIZE, 0);
        let r = self.inner.read(&mut self.buf[old..]);
        let n = *r.as_ref().unwrap_or(&0);
        self.buf.truncate(old + n);
        r
    }

    fn consume(&mut self, n: usize) {
        self.pos += n;
        self.consumed += n as u64;
    }

    /// One line without its `\n` (and a `\r` before it). `Ok(None)` at a clean end of input;
    /// an error when the line is longer than `cap` or the input ends inside it.
    pub fn read_line(&mut self, cap: usize) -> io::Result<Option<Vec<u8>>> {
        let mut scanned = 0;
        loop {
            if let Some(i) = self.available()[scanned..].iter().position(|&b| b == b'\n') {
                let end = scanned + i;
                let mut line = self.available()[..end].to_vec();
                if line.last() == Some(&b'\r') {
                    line.pop();
                }
                self.consume(end + 1);
                return Ok(Some(line));
            }
            scanned = self.available().len();
            if scanned > cap {
                return Err(invalid(format!("a line longer than {cap} bytes")));
            }
            if self.fill()? == 0 {
                return if self.available().is_empty() {
                    Ok(None)
                } else {
                    Err(eof("inside a line"))
                };
            }
        }
    }

    /// Exactly `n` bytes.
    pub fn read_exact_vec(&mut self, n: usize) -> io::Result<Vec<u8>> {
        let mut out = Vec::with_capacity(n);
        while out.len() < n {
            if self.available().is_empty() && self.fill()? == 0 {
                return Err(eof(&format!("after {} of {n} bytes", out.len())));
            }
            let take = (n - out.len()).min(self.available().len());
            out.extend_from_slice(&self.available()[..take]);
            self.consume(take);
        }
        Ok(out)
    }

    /// Up to `n` bytes (at least one unless the input ended).
    pub fn read_some(&mut self, n: usize) -> io::Result<Vec<u8>> {
        if self.available().is_empty() && self.fill()? == 0 {
            return Ok(Vec::new());
        }
        let take = n.min(self.available().len());
        let out = self.available()[..take].to_vec();
        self.consume(take);
        Ok(out)
    }

    /// Everything before the first occurrence of `delim`; the delimiter stays unread. An error
    /// when more than `cap` bytes come first or the input ends.
    pub fn read_until(&mut self, delim: &[u8], cap: usize) -> io::Result<Vec<u8>> {
        let mut from = 0;
        loop {
            let a = self.available();
            if let Some(i) = find(&a[from..], delim) {
                let body = a[..from + i].to_vec();
                self.consume(from + i);
                return Ok(body);
            }
            from = a.len().saturating_sub(delim.len().saturating_sub(1));
            if a.len() > cap + delim.len() {
                return Err(invalid(format!(
                    "a part longer than {cap} bytes without a boundary"
                )));
            }
            if self.fill()? == 0 {
                return Err(eof("before the next boundary"));
            }
        }
    }
}

/// The first position of `needle` in `hay`.
pub fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    if needle.is_empty() {
        return Some(0);
    }
    hay.windows(needle.len()).position(|w| w == needle)
}

fn invalid(msg: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidData, msg)
}

fn eof(where_: &str) -> io::Error {
    io::Error::new(
        io::ErrorKind::UnexpectedEof,
        format!("the connection closed {where_}"),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reader that gives one byte per call, to cross every buffer boundary.
    struct Trickle<'a>(&'a [u8]);
    impl Read for Trickle<'_> {
        fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            if self.0.is_empty() || buf.is_empty() {
                return Ok(0);
            }
            buf[0] = self.0[0];
            self.0 = &self.0[1..];
            Ok(1)
        }
    }

    #[test]
    fn lines_exact_reads_and_delimiters_across_reads() {
        let data = b"HTTP/1.1 200 OK\r\nA: b\n\r\nxyzBODY--bnd rest";
        let mut i = Input::new(Trickle(data));
        assert_eq!(i.read_line(100).unwrap().unwrap(), b"HTTP/1.1 200 OK");
        assert_eq!(i.read_line(100).unwrap().unwrap(), b"A: b");
        assert_eq!(i.read_line(100).unwrap().unwrap(), b"");
        assert_eq!(i.read_exact_vec(3).unwrap(), b"xyz");
        assert_eq!(i.read_until(b"--bnd", 100).unwrap(), b"BODY");
        assert_eq!(i.read_exact_vec(5).unwrap(), b"--bnd");
        assert!(i.read_line(100).is_err(), "input ends inside a line");
        let mut i = Input::new(Trickle(b"aaaaaaaaaaaaaaaaaaaa"));
        assert!(i.read_until(b"--x", 5).is_err());
        let mut i = Input::new(Trickle(b"aaaaaaaaaaaaaaaa"));
        assert!(i.read_line(4).is_err());
        let mut i = Input::new(Trickle(b""));
        assert!(i.read_line(4).unwrap().is_none());
    }
}
