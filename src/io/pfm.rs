//! Portable Float Map (PFM) images and PFM flow files: `Pf` (grey) and `PF` (colour).
//!
//! Header: magic, width, height, scale (ASCII, whitespace separated, `#` comments allowed),
//! then one whitespace byte and `W*H*C` f32 samples, pixel-interleaved, rows stored bottom to
//! top. A negative scale means little-endian samples, a positive one big-endian.

use std::path::Path;

use super::atomic::{read_bytes, write_bytes_atomic};
use super::budget;
use super::unknown::unknown_to_nan;
use crate::error::{Error, Result};
use crate::types::{Flow, Image};

/// Largest width or height that parses (the pixel budget then bounds W·H).
const MAX_SIDE: usize = 1 << 31;

/// Reads a PFM file as an image `[C, H, W]` (C = 1 for `Pf`, 3 for `PF`), top row first.
/// Samples are returned as stored (PFM is linear float; no scaling is applied). The declared
/// size is checked against the pixel budget ([`super::budget`]) before decoding.
pub fn read_pfm(path: &Path) -> Result<Image> {
    let bytes = read_bytes(path)?;
    decode_pfm(&bytes, path)
}

/// Reads a PFM flow file (e.g. FlyingThings3D): a 3-channel `PF` whose first two channels are
/// u and v; the third is ignored. Grey `Pf` files are rejected. Unknown vectors (a component
/// non-finite or of magnitude `>= 1e9`) become NaN.
pub fn read_pfm_flow(path: &Path) -> Result<Flow> {
    decode_pfm_flow(&read_bytes(path)?, path)
}

/// Decodes PFM flow bytes as [`read_pfm_flow`] does; `path` is used only in error messages.
pub fn decode_pfm_flow(bytes: &[u8], path: &Path) -> Result<Flow> {
    let im = decode_pfm(bytes, path)?;
    if im.channels() < 2 {
        return Err(Error::format(
            path,
            format!(
                "a PFM flow file needs at least 2 channels (u, v), found {} (grey 'Pf')",
                im.channels()
            ),
        ));
    }
    let (h, w) = (im.height(), im.width());
    let mut data = im.into_vec();
    data.truncate(2 * h * w);
    unknown_to_nan(&mut data);
    Flow::from_vec(h, w, data)
}

/// Writes a flow field as FlyingThings3D stores it, atomically: colour PFM (`PF`), channels
/// u, v and a zero third, little endian (scale -1.0), rows bottom to top; unknown (NaN)
/// vectors are written as NaN. RAFT's `readPFM` reads it back (flipping the rows and keeping
/// the first two channels).
pub fn write_pfm_flow(path: &Path, flow: &Flow) -> Result<()> {
    let (h, w) = (flow.height(), flow.width());
    if h == 0 || w == 0 {
        return Err(Error::invalid(
            format!("flow for {}", path.display()),
            format!("cannot write an empty {w}x{h} flow as PFM"),
        ));
    }
    let mut out = Vec::with_capacity(32 + 12 * h * w);
    out.extend_from_slice(format!("PF\n{w} {h}\n-1.0\n").as_bytes());
    for y in (0..h).rev() {
        let (u, v) = (&flow.u()[y * w..][..w], &flow.v()[y * w..][..w]);
        for (a, b) in u.iter().zip(v) {
            out.extend_from_slice(&a.to_le_bytes());
            out.extend_from_slice(&b.to_le_bytes());
            out.extend_from_slice(&0.0f32.to_le_bytes());
        }
    }
    write_bytes_atomic(path, &out)
}

/// Writes a 1-channel (`Pf`) or 3-channel (`PF`) image as little-endian PFM (scale -1),
/// rows bottom to top, atomically.
pub fn write_pfm(path: &Path, image: &Image) -> Result<()> {
    let (c, h, w) = image.shape();
    let magic = match c {
        1 => "Pf",
        3 => "PF",
        _ => {
            return Err(Error::invalid(
                format!("image for {}", path.display()),
                format!("PFM stores 1 or 3 channels, image has {c}"),
            ));
        }
    };
    let mut out = Vec::with_capacity(32 + 4 * c * h * w);
    out.extend_from_slice(format!("{magic}\n{w} {h}\n-1.0\n").as_bytes());
    for y in (0..h).rev() {
        for x in 0..w {
            for ch in 0..c {
                out.extend_from_slice(&image.get(ch, y, x).to_le_bytes());
            }
        }
    }
    write_bytes_atomic(path, &out)
}

/// A cursor over the ASCII header.
struct Header<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl Header<'_> {
    /// Skips whitespace and `#` comments (to end of line).
    fn skip_space(&mut self) {
        while let Some(&b) = self.bytes.get(self.pos) {
            if b.is_ascii_whitespace() {
                self.pos += 1;
            } else if b == b'#' {
                while let Some(&c) = self.bytes.get(self.pos) {
                    self.pos += 1;
                    if c == b'\n' || c == b'\r' {
                        break;
                    }
                }
            } else {
                break;
            }
        }
    }

    /// The next whitespace-delimited token, as text.
    fn token(&mut self, what: &str, path: &Path) -> Result<String> {
        self.skip_space();
        let start = self.pos;
        while self
            .bytes
            .get(self.pos)
            .is_some_and(|b| !b.is_ascii_whitespace() && *b != b'#')
        {
            self.pos += 1;
        }
        if start == self.pos || self.pos - start > 64 {
            return Err(Error::format(
                path,
                format!("PFM header: missing or malformed {what} at byte {start}"),
            ));
        }
        Ok(String::from_utf8_lossy(&self.bytes[start..self.pos]).into_owned())
    }
}

/// Decodes PFM bytes; `path` is used only in error messages.
pub fn decode_pfm(bytes: &[u8], path: &Path) -> Result<Image> {
    let channels = match bytes.get(..2) {
        Some(b"PF") => 3,
        Some(b"Pf") => 1,
        _ => {
            let found: String = bytes
                .iter()
                .take(2)
                .map(|&b| if b.is_ascii_graphic() { b as char } else { '?' })
                .collect();
            return Err(Error::format(
                path,
                format!("not a PFM file: expected magic 'PF' or 'Pf', found {found:?}"),
            ));
        }
    };
    if bytes.get(2).is_some_and(|b| !b.is_ascii_whitespace()) {
        return Err(Error::format(
            path,
            "PFM header: magic must be followed by whitespace",
        ));
    }
    let mut hd = Header { bytes, pos: 2 };
    let mut dim = |what: &str| -> Result<usize> {
        let t = hd.token(what, path)?;
        t.parse::<usize>()
            .ok()
            .filter(|&v| v > 0 && v <= MAX_SIDE)
            .ok_or_else(|| {
                Error::format(
                    path,
                    format!("PFM header: {what} must be an integer in 1..={MAX_SIDE}, found {t:?}"),
                )
            })
    };
    let w = dim("width")?;
    let h = dim("height")?;
    let t = hd.token("scale", path)?;
    let scale: f32 = t
        .parse()
        .ok()
        .filter(|s: &f32| s.is_finite() && *s != 0.0)
        .ok_or_else(|| {
            Error::format(
                path,
                format!("PFM header: scale must be a non-zero number, found {t:?}"),
            )
        })?;
    budget::check_pixels(path, "PFM image", w as u64, h as u64, channels as u64)?;
    // Exactly one whitespace byte separates the header from the data.
    match bytes.get(hd.pos) {
        Some(b) if b.is_ascii_whitespace() => hd.pos += 1,
        _ => {
            return Err(Error::format(
                path,
                "PFM header: no whitespace after the scale",
            ));
        }
    }
    let n = w * h * channels;
    let need = 4 * n;
    // Tolerate a CR LF line ending (only when the LF is not part of the data).
    if bytes.get(hd.pos - 1) == Some(&b'\r')
        && bytes.get(hd.pos) == Some(&b'\n')
        && bytes.len() - hd.pos > need
    {
        hd.pos += 1;
    }
    let payload = &bytes[hd.pos..];
    if payload.len() < need {
        return Err(Error::format(
            path,
            format!(
                "truncated PFM: {w}x{h}x{channels} needs {need} data bytes, found {}",
                payload.len()
            ),
        ));
    }
    if payload[need..].iter().any(|b| !b.is_ascii_whitespace()) {
        return Err(Error::format(
            path,
            format!(
                "oversized PFM: {w}x{h}x{channels} needs {need} data bytes, found {}",
                payload.len()
            ),
        ));
    }
    let little = scale < 0.0;
    let mut im = Image::zeros(channels, h, w);
    for (i, s) in payload[..need].chunks_exact(4).enumerate() {
        let b = [s[0], s[1], s[2], s[3]];
        let v = if little {
            f32::from_le_bytes(b)
        } else {
            f32::from_be_bytes(b)
        };
        let ch = i % channels;
        let px = i / channels;
        let (row_from_bottom, x) = (px / w, px % w);
        im.set(ch, h - 1 - row_from_bottom, x, v);
    }
    Ok(im)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(c: usize, h: usize, w: usize) -> Image {
        let data = (0..c * h * w).map(|i| i as f32 / 7.0 - 1.5).collect();
        Image::from_vec(c, h, w, data).unwrap()
    }

    #[test]
    fn grey_and_colour_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        for c in [1, 3] {
            let p = dir.path().join(format!("a{c}.pfm"));
            let im = ramp(c, 4, 5);
            write_pfm(&p, &im).unwrap();
            let bytes = std::fs::read(&p).unwrap();
            let magic: &[u8] = if c == 1 {
                b"Pf\n5 4\n-1.0\n"
            } else {
                b"PF\n5 4\n-1.0\n"
            };
            assert!(bytes.starts_with(magic));
            assert_eq!(read_pfm(&p).unwrap(), im);
        }
        let p = dir.path().join("bad.pfm");
        assert!(write_pfm(&p, &ramp(2, 2, 2)).is_err());
        assert!(!p.exists());
    }

    #[test]
    fn bottom_to_top_big_endian_with_comments() {
        // 1x2 grey, big-endian: stored rows bottom first, so the top pixel is the second value.
        let mut b = b"Pf\n# a comment\n 1   2 # trailing\n1.0\n".to_vec();
        b.extend_from_slice(&10.0f32.to_be_bytes());
        b.extend_from_slice(&20.0f32.to_be_bytes());
        let im = decode_pfm(&b, Path::new("c.pfm")).unwrap();
        assert_eq!(im.shape(), (1, 2, 1));
        assert_eq!(im.get(0, 0, 0), 20.0);
        assert_eq!(im.get(0, 1, 0), 10.0);
        // CR LF after the scale, and a lone CR followed by data starting with byte 0x0A.
        let mut b = b"Pf\r\n1 1\r\n-1\r\n".to_vec();
        b.extend_from_slice(&3.0f32.to_le_bytes());
        assert_eq!(decode_pfm(&b, Path::new("d.pfm")).unwrap().data(), &[3.0]);
        let mut b = b"Pf\n1 1\n-1\r".to_vec();
        b.extend_from_slice(&[0x0a, 0, 0, 0]);
        let v = f32::from_le_bytes([0x0a, 0, 0, 0]);
        assert_eq!(decode_pfm(&b, Path::new("e.pfm")).unwrap().data(), &[v]);
    }

    #[test]
    fn flow_from_three_channels() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("f.pfm");
        let im = ramp(3, 2, 3);
        write_pfm(&p, &im).unwrap();
        let f = read_pfm_flow(&p).unwrap();
        assert_eq!(f.u(), im.plane(0));
        assert_eq!(f.v(), im.plane(1));
        write_pfm(&p, &ramp(1, 2, 3)).unwrap();
        assert!(read_pfm_flow(&p).is_err());
    }

    #[test]
    fn header_errors_are_clear() {
        let e = |b: &[u8]| decode_pfm(b, Path::new("e.pfm")).unwrap_err().to_string();
        assert!(e(b"P6\n1 1\n255\n").contains("magic"));
        assert!(e(b"Pf\n0 1\n-1\n    ").contains("width"));
        assert!(e(b"Pf\n1 x\n-1\n    ").contains("height"));
        assert!(e(b"Pf\n1 1\nabc\n    ").contains("scale"));
        assert!(e(b"Pf\n2 1\n-1\n\0\0\0\0").contains("truncated"));
        assert!(e(b"Pf\n1 1\n-1\n\0\0\0\0\x01").contains("oversized"));
        assert!(e(b"Pf\n1").contains("height"));
    }

    #[test]
    fn flow_is_written_as_flyingthings3d_stores_it() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("f.pfm");
        let (h, w) = (3, 4);
        let mut f =
            Flow::from_vec(h, w, (0..2 * h * w).map(|i| i as f32 * 0.5 - 3.0).collect()).unwrap();
        f.set(1, 2, f32::NAN, f32::NAN);
        f.set(0, 1, 7.25, -1.5);
        write_pfm_flow(&p, &f).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        // RAFT's readPFM: header line "PF", then "W H", then the scale (negative: little endian).
        let header = b"PF\n4 3\n-1.0\n";
        assert!(bytes.starts_with(header));
        assert_eq!(bytes.len(), header.len() + 4 * 3 * h * w);
        // Pixel (row 0, column 1) is stored in the last row (rows go bottom to top), as
        // (u, v, 0) little-endian f32.
        let at = header.len() + 12 * ((h - 1) * w + 1);
        let word = |i: usize| f32::from_le_bytes(bytes[i..i + 4].try_into().unwrap());
        assert_eq!((word(at), word(at + 4), word(at + 8)), (7.25, -1.5, 0.0));
        // Unknown stays NaN in the file, and everything round-trips.
        let at = header.len() + 12 * ((h - 1 - 1) * w + 2);
        assert!(word(at).is_nan() && word(at + 4).is_nan() && word(at + 8) == 0.0);
        let back = read_pfm_flow(&p).unwrap();
        assert_eq!(back.valid_mask(), f.valid_mask());
        for (a, b) in back.data().iter().zip(f.data()) {
            assert!(a == b || (a.is_nan() && b.is_nan()));
        }
        assert!(write_pfm_flow(&dir.path().join("e.pfm"), &Flow::zeros(0, 2)).is_err());
        assert!(!dir.path().join("e.pfm").exists());
    }

    #[test]
    fn unknown_flow_is_nan_in_both_components() {
        let mut b = b"PF\n4 1\n-1.0\n".to_vec();
        for v in [
            f32::NAN,
            1.0,
            0.0,
            2.0,
            f32::NEG_INFINITY,
            0.0,
            1e9,
            0.0,
            0.0,
            -0.5,
            0.25,
            9.0,
        ] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        let f = decode_pfm_flow(&b, Path::new("u.pfm")).unwrap();
        for x in 0..3 {
            let (u, v) = f.get(0, x);
            assert!(u.is_nan() && v.is_nan(), "pixel {x}: ({u}, {v})");
        }
        assert_eq!(f.get(0, 3), (-0.5, 0.25));
    }
}
