//! Middlebury `.flo` optical-flow files: read, decode, encode, write.
//!
//! Layout: magic `202021.25` (f32 LE), width (i32 LE), height (i32 LE), then `H*W` interleaved
//! `(u, v)` f32 LE pairs, rows top to bottom. Components with magnitude `>= 1e9` mark unknown
//! flow (Middlebury convention); they, and non-finite components, are read as NaN vectors.

use std::path::Path;

use super::atomic::{read_bytes, write_bytes_atomic};
use super::budget;
use super::unknown::is_unknown;
use crate::error::{Error, Result};
use crate::types::Flow;

/// The `.flo` magic number, stored as a little-endian `f32` ("PIEH" in ASCII).
pub const FLO_MAGIC: f32 = 202021.25;
pub use super::unknown::UNKNOWN_THRESHOLD;

const HEADER_LEN: usize = 12;

/// Reads a Middlebury `.flo` file; unknown vectors become NaN. The declared size is checked
/// against the pixel budget ([`super::budget`]) before anything else.
pub fn read_flo(path: &Path) -> Result<Flow> {
    let bytes = read_bytes(path)?;
    decode_flo(&bytes, path)
}

/// Decodes the bytes of a `.flo` file; `path` is used only in error messages.
pub fn decode_flo(bytes: &[u8], path: &Path) -> Result<Flow> {
    if bytes.len() < HEADER_LEN {
        return Err(Error::format(
            path,
            format!(
                "not a .flo file: {} bytes, shorter than the {HEADER_LEN}-byte header",
                bytes.len()
            ),
        ));
    }
    let word = |i: usize| [bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]];
    let magic = f32::from_le_bytes(word(0));
    if magic != FLO_MAGIC {
        return Err(Error::format(
            path,
            format!(
                "bad .flo magic: expected {FLO_MAGIC} (bytes 50 49 45 48 \"PIEH\"), found {magic} \
                 (bytes {:02x} {:02x} {:02x} {:02x})",
                bytes[0], bytes[1], bytes[2], bytes[3]
            ),
        ));
    }
    let w = i32::from_le_bytes(word(4));
    let h = i32::from_le_bytes(word(8));
    if w <= 0 || h <= 0 {
        return Err(Error::format(
            path,
            format!(".flo size must be positive, found width {w}, height {h}"),
        ));
    }
    budget::check_pixels(path, ".flo flow", w as u64, h as u64, 2)?;
    let (w, h) = (w as usize, h as usize);
    let n = w * h;
    let expected = HEADER_LEN + 8 * n;
    if bytes.len() != expected {
        let what = if bytes.len() < expected {
            "truncated"
        } else {
            "oversized"
        };
        return Err(Error::format(
            path,
            format!(
                "{what} .flo file: a {w}x{h} field needs {expected} bytes, found {}",
                bytes.len()
            ),
        ));
    }
    let mut data = vec![0.0f32; 2 * n];
    let (u, v) = data.split_at_mut(n);
    for (i, pair) in bytes[HEADER_LEN..].chunks_exact(8).enumerate() {
        let a = f32::from_le_bytes([pair[0], pair[1], pair[2], pair[3]]);
        let b = f32::from_le_bytes([pair[4], pair[5], pair[6], pair[7]]);
        if is_unknown(a, b) {
            u[i] = f32::NAN;
            v[i] = f32::NAN;
        } else {
            u[i] = a;
            v[i] = b;
        }
    }
    Flow::from_vec(h, w, data)
}

/// Encodes a flow field as `.flo` bytes. Non-finite vectors are written as the Middlebury
/// unknown value `1e10` so that other tools recognise them.
pub fn encode_flo(flow: &Flow) -> Vec<u8> {
    let (w, h) = (flow.width(), flow.height());
    let mut out = Vec::with_capacity(HEADER_LEN + 8 * w * h);
    out.extend_from_slice(&FLO_MAGIC.to_le_bytes());
    out.extend_from_slice(&(w as i32).to_le_bytes());
    out.extend_from_slice(&(h as i32).to_le_bytes());
    for (&a, &b) in flow.u().iter().zip(flow.v()) {
        let (a, b) = if a.is_finite() && b.is_finite() {
            (a, b)
        } else {
            (1e10, 1e10)
        };
        out.extend_from_slice(&a.to_le_bytes());
        out.extend_from_slice(&b.to_le_bytes());
    }
    out
}

/// Writes a `.flo` file atomically. Fails for empty fields or sides that do not fit an `i32`.
pub fn write_flo(path: &Path, flow: &Flow) -> Result<()> {
    let (w, h) = (flow.width(), flow.height());
    if w == 0 || h == 0 || w > i32::MAX as usize || h > i32::MAX as usize {
        return Err(Error::invalid(
            format!("flow for {}", path.display()),
            format!(".flo needs a non-empty size that fits in i32, got {w}x{h}"),
        ));
    }
    write_bytes_atomic(path, &encode_flo(flow))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Flow {
        let (h, w) = (3, 5);
        let data = (0..2 * h * w).map(|i| i as f32 * 0.37 - 4.0).collect();
        Flow::from_vec(h, w, data).unwrap()
    }

    fn header(w: i32, h: i32) -> Vec<u8> {
        let mut b = FLO_MAGIC.to_le_bytes().to_vec();
        b.extend_from_slice(&w.to_le_bytes());
        b.extend_from_slice(&h.to_le_bytes());
        b
    }

    #[test]
    fn byte_exact_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.flo");
        let f = sample();
        write_flo(&p, &f).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        assert_eq!(bytes.len(), 12 + 8 * 15);
        let back = read_flo(&p).unwrap();
        assert_eq!(back, f);
        assert_eq!(encode_flo(&back), bytes);
        // Interleaving: the first pair is (u[0], v[0]).
        assert_eq!(&bytes[12..16], &f.u()[0].to_le_bytes());
        assert_eq!(&bytes[16..20], &f.v()[0].to_le_bytes());
    }

    #[test]
    fn unknown_becomes_nan_and_back() {
        let mut b = header(2, 1);
        for v in [1.0f32, 2.0, 1e9, 0.5] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        let f = decode_flo(&b, Path::new("x.flo")).unwrap();
        assert_eq!(f.get(0, 0), (1.0, 2.0));
        assert!(f.get(0, 1).0.is_nan() && f.get(0, 1).1.is_nan());
        let again = decode_flo(&encode_flo(&f), Path::new("y.flo")).unwrap();
        assert_eq!(again.valid_mask(), vec![true, false]);
    }

    #[test]
    fn rejects_bad_magic() {
        let mut b = header(1, 1);
        b[0] = b'X';
        b.extend_from_slice(&[0; 8]);
        let e = decode_flo(&b, Path::new("m.flo")).unwrap_err().to_string();
        assert!(
            e.contains("m.flo") && e.contains("magic") && e.contains("found"),
            "{e}"
        );
    }

    #[test]
    fn rejects_truncated_and_oversized() {
        let mut b = header(2, 2);
        b.extend_from_slice(&[0; 31]);
        let e = decode_flo(&b, Path::new("t.flo")).unwrap_err().to_string();
        assert!(
            e.contains("truncated") && e.contains("44") && e.contains("43"),
            "{e}"
        );
        b.extend_from_slice(&[0; 2]);
        let e = decode_flo(&b, Path::new("t.flo")).unwrap_err().to_string();
        assert!(
            e.contains("oversized") && e.contains("44") && e.contains("45"),
            "{e}"
        );
        let e = decode_flo(&b[..7], Path::new("t.flo"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("header"), "{e}");
    }

    #[test]
    fn rejects_zero_negative_and_absurd_sizes() {
        for (w, h) in [(0, 4), (4, 0), (-3, 2), (200_000, 1), (50_000, 50_000)] {
            let e = decode_flo(&header(w, h), Path::new("s.flo")).unwrap_err();
            assert!(matches!(e, Error::Format { .. }), "{w}x{h}: {e}");
        }
    }

    #[test]
    fn write_rejects_empty_and_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("e.flo");
        assert!(write_flo(&p, &Flow::zeros(0, 3)).is_err());
        assert!(!p.exists());
    }

    #[test]
    fn non_finite_components_make_the_whole_vector_unknown() {
        // A NaN or infinite component (not only >= 1e9) is unknown, and so is its partner.
        let mut b = header(4, 1);
        for v in [f32::NAN, 2.0, 1.0, f32::INFINITY, -1e9, 0.0, 3.0, -4.0] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        let f = decode_flo(&b, Path::new("n.flo")).unwrap();
        for x in 0..3 {
            let (u, v) = f.get(0, x);
            assert!(u.is_nan() && v.is_nan(), "pixel {x}: ({u}, {v})");
        }
        assert_eq!(f.get(0, 3), (3.0, -4.0));
    }

    #[test]
    fn budget_refuses_before_the_length_check() {
        let e = decode_flo(&header(16000, 16000), Path::new("h.flo"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("h.flo") && e.contains("16000x16000") && e.contains("--max-pixels"),
            "{e}"
        );
    }
}
