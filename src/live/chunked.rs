//! HTTP/1.1 chunked transfer decoding (RFC 9112 §7.1): `SIZE[;ext]\r\n DATA \r\n` repeated, a
//! zero-size chunk at the end. The ESP32 never sends the last chunk; its frames arrive as three
//! chunks each (part header, JPEG, CRLF), which the multipart reader above never sees.

use std::io::{self, Read};

use super::input::Input;

/// The longest chunk-size line accepted (hex digits and extensions).
const MAX_SIZE_LINE: usize = 1024;

/// A reader of the data inside chunked transfer coding.
pub struct Chunked<R> {
    input: Input<R>,
    /// Bytes left in the current chunk.
    left: u64,
    done: bool,
}

impl<R: Read> Chunked<R> {
    pub fn new(input: Input<R>) -> Self {
        Self {
            input,
            left: 0,
            done: false,
        }
    }

    /// Reads the next chunk-size line (after the CRLF ending the previous chunk's data).
    fn next_chunk(&mut self, first: bool) -> io::Result<()> {
        if !first {
            let crlf = self
                .input
                .read_line(MAX_SIZE_LINE)?
                .ok_or_else(|| io::Error::new(io::ErrorKind::UnexpectedEof, "stream ended"))?;
            if !crlf.is_empty() {
                return Err(bad("chunk data not followed by CRLF"));
            }
        }
        let line = self
            .input
            .read_line(MAX_SIZE_LINE)?
            .ok_or_else(|| io::Error::new(io::ErrorKind::UnexpectedEof, "stream ended"))?;
        let text = String::from_utf8_lossy(&line);
        let hex = text.split(';').next().unwrap_or("").trim();
        if hex.is_empty() || hex.len() > 15 {
            return Err(bad(&format!("bad chunk size line {text:?}")));
        }
        self.left = u64::from_str_radix(hex, 16)
            .map_err(|_| bad(&format!("bad chunk size line {text:?}")))?;
        if self.left == 0 {
            self.done = true;
        }
        Ok(())
    }
}

/// The `Read` side of [`Chunked`]: the data of the chunks, in order.
pub struct ChunkedReader<R> {
    chunked: Chunked<R>,
    started: bool,
}

impl<R: Read> ChunkedReader<R> {
    pub fn new(input: Input<R>) -> Self {
        Self {
            chunked: Chunked::new(input),
            started: false,
        }
    }
}

impl<R: Read> Read for ChunkedReader<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let c = &mut self.chunked;
        if buf.is_empty() {
            return Ok(0);
        }
        while !c.done && c.left == 0 {
            c.next_chunk(!self.started)?;
            self.started = true;
        }
        if c.done {
            return Ok(0);
        }
        let want = (c.left.min(buf.len() as u64)) as usize;
        let data = c.input.read_some(want)?;
        if data.is_empty() {
            return Err(io::Error::new(
                io::ErrorKind::UnexpectedEof,
                "the connection closed inside a chunk",
            ));
        }
        buf[..data.len()].copy_from_slice(&data);
        c.left -= data.len() as u64;
        Ok(data.len())
    }
}

fn bad(msg: &str) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidData, msg.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn decode(wire: &[u8]) -> io::Result<Vec<u8>> {
        let mut out = Vec::new();
        ChunkedReader::new(Input::new(wire)).read_to_end(&mut out)?;
        Ok(out)
    }

    #[test]
    fn chunks_are_joined_and_bad_sizes_refused() {
        assert_eq!(
            decode(b"3\r\nabc\r\nA;x=1\r\n0123456789\r\n0\r\n\r\n").unwrap(),
            b"abc0123456789"
        );
        assert!(decode(b"zz\r\nabc\r\n").is_err());
        assert!(
            decode(b"3\r\nabcd\r\n").is_err(),
            "data longer than its size"
        );
        assert!(decode(b"5\r\nab").is_err(), "closed inside a chunk");
        assert!(decode(b"ffffffffffffffffff\r\n").is_err());
    }
}
