//! NumPy `.npy` arrays (format versions 1, 2 and 3) as images: read several dtypes, write `<f4`.
//!
//! Shapes: `[H, W]` is one channel; `[H, W, C]` with `C` in 1..=4 is channel-last; otherwise
//! `[C, H, W]` with `C` in 1..=4 is channel-first. Written files are `[C, H, W]` (or `[H, W]`
//! for one channel), so an image whose width is 1..=4 does not round-trip unambiguously.

use std::path::Path;

use super::atomic::{read_bytes, write_bytes_atomic};
use super::budget;
use crate::error::{Error, Result};
use crate::types::Image;

const MAGIC: &[u8] = b"\x93NUMPY";

/// Element types accepted by [`read_npy`].
#[derive(Clone, Copy, Debug)]
enum Dtype {
    F4 { little: bool },
    F8 { little: bool },
    U1,
    U2 { little: bool },
}

impl Dtype {
    fn parse(s: &str) -> Option<Self> {
        Some(match s {
            "<f4" => Dtype::F4 { little: true },
            ">f4" => Dtype::F4 { little: false },
            "<f8" => Dtype::F8 { little: true },
            ">f8" => Dtype::F8 { little: false },
            "|u1" | "<u1" | ">u1" => Dtype::U1,
            "<u2" => Dtype::U2 { little: true },
            ">u2" => Dtype::U2 { little: false },
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Dtype::F4 { .. } => 4,
            Dtype::F8 { .. } => 8,
            Dtype::U1 => 1,
            Dtype::U2 { .. } => 2,
        }
    }

    /// One element as f32: floats as-is, u1 / 255, u2 / 65535.
    fn value(self, b: &[u8]) -> f32 {
        match self {
            Dtype::F4 { little } => {
                let a = [b[0], b[1], b[2], b[3]];
                if little {
                    f32::from_le_bytes(a)
                } else {
                    f32::from_be_bytes(a)
                }
            }
            Dtype::F8 { little } => {
                let a = [b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]];
                (if little {
                    f64::from_le_bytes(a)
                } else {
                    f64::from_be_bytes(a)
                }) as f32
            }
            Dtype::U1 => f32::from(b[0]) / 255.0,
            Dtype::U2 { little } => {
                let a = [b[0], b[1]];
                f32::from(if little {
                    u16::from_le_bytes(a)
                } else {
                    u16::from_be_bytes(a)
                }) / 65535.0
            }
        }
    }
}

/// The value text following `'key':` in the header dictionary (up to the next top-level comma
/// or closing brace), trimmed.
fn dict_value<'a>(header: &'a str, key: &str) -> Option<&'a str> {
    let at = header
        .find(&format!("'{key}'"))
        .or_else(|| header.find(&format!("\"{key}\"")))?;
    let rest = header[at + key.len() + 2..]
        .trim_start()
        .strip_prefix(':')?;
    let rest = rest.trim_start();
    let end = if rest.starts_with('(') {
        rest.find(')')? + 1
    } else {
        rest.find([',', '}']).unwrap_or(rest.len())
    };
    Some(rest[..end].trim())
}

/// Reads a `.npy` array as an image (see the module documentation for shapes and dtypes). The
/// declared shape is checked against the pixel budget ([`super::budget`]) before decoding.
pub fn read_npy(path: &Path) -> Result<Image> {
    let bytes = read_bytes(path)?;
    decode_npy(&bytes, path)
}

/// Decodes `.npy` bytes; `path` is used only in error messages.
pub fn decode_npy(bytes: &[u8], path: &Path) -> Result<Image> {
    let fail = |reason: String| Error::format(path, reason);
    if !bytes.starts_with(MAGIC) || bytes.len() < 10 {
        return Err(fail("not a .npy file: missing the \\x93NUMPY magic".into()));
    }
    let major = bytes[6];
    let (len, start): (usize, usize) = match major {
        1 => (usize::from(u16::from_le_bytes([bytes[8], bytes[9]])), 10),
        2 | 3 if bytes.len() >= 12 => {
            let n = u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]);
            (n as usize, 12)
        }
        _ => {
            return Err(fail(format!(
                "unsupported .npy format version {major}.{}",
                bytes[7]
            )));
        }
    };
    let header = bytes
        .get(start..start.saturating_add(len))
        .ok_or_else(|| fail(format!("truncated .npy header: {len} bytes announced")))?;
    let header: String = if major == 3 {
        String::from_utf8_lossy(header).into_owned()
    } else {
        header.iter().map(|&b| b as char).collect() // latin-1
    };
    let descr = dict_value(&header, "descr")
        .ok_or_else(|| fail(format!("no 'descr' in .npy header {header:?}")))?
        .trim_matches(['\'', '"']);
    let dtype = Dtype::parse(descr).ok_or_else(|| {
        fail(format!(
            "unsupported .npy dtype {descr:?}; supported: <f4 <f8 |u1 <u2 >f4 >f8 >u2"
        ))
    })?;
    match dict_value(&header, "fortran_order") {
        Some("False") => {}
        Some("True") => {
            return Err(fail(
                "fortran_order is True: only C-order arrays are supported \
                 (save with np.ascontiguousarray)"
                    .into(),
            ));
        }
        other => {
            return Err(fail(format!(
                "bad or missing 'fortran_order' in .npy header: {other:?}"
            )));
        }
    }
    let shape_text = dict_value(&header, "shape")
        .ok_or_else(|| fail(format!("no 'shape' in .npy header {header:?}")))?;
    let shape: Vec<usize> = shape_text
        .trim_start_matches('(')
        .trim_end_matches(')')
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| {
            s.parse::<usize>()
                .map_err(|_| fail(format!("bad .npy shape {shape_text}")))
        })
        .collect::<Result<_>>()?;
    let (c, h, w, channel_last) = match shape[..] {
        [h, w] => (1, h, w, false),
        [h, w, c] if (1..=4).contains(&c) => (c, h, w, true),
        [c, h, w] if (1..=4).contains(&c) => (c, h, w, false),
        _ => {
            return Err(fail(format!(
                "unsupported .npy shape {shape:?}: expected [H, W], [H, W, C] or [C, H, W] \
                 with C in 1..=4"
            )));
        }
    };
    if c == 0 || h == 0 || w == 0 {
        return Err(fail(format!(
            "empty .npy array of shape {shape:?}: an image needs at least one pixel"
        )));
    }
    budget::check_pixels(path, ".npy array", w as u64, h as u64, c as u64)?;
    let n = c
        .checked_mul(h)
        .and_then(|v| v.checked_mul(w))
        .ok_or_else(|| fail(format!(".npy shape {shape:?} is implausibly large")))?;
    let payload = &bytes[start + len..];
    let need = n * dtype.size();
    if payload.len() != need {
        let what = if payload.len() < need {
            "truncated"
        } else {
            "oversized"
        };
        return Err(fail(format!(
            "{what} .npy data: shape {shape:?} of {descr} needs {need} bytes, found {}",
            payload.len()
        )));
    }
    let mut data = vec![0.0f32; n];
    let hw = h * w;
    for (i, e) in payload.chunks_exact(dtype.size()).enumerate() {
        let dst = if channel_last {
            (i % c) * hw + i / c
        } else {
            i
        };
        data[dst] = dtype.value(e);
    }
    Image::from_vec(c, h, w, data)
}

/// Encodes an image as `.npy` v1 bytes, dtype `<f4`, shape `[C, H, W]` or `[H, W]`.
pub fn encode_npy(image: &Image) -> Vec<u8> {
    let (c, h, w) = image.shape();
    let shape = if c == 1 {
        format!("({h}, {w})")
    } else {
        format!("({c}, {h}, {w})")
    };
    let mut header = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {shape}, }}");
    // Pad with spaces so that the data starts on a 64-byte boundary; end with a newline.
    let unpadded = MAGIC.len() + 4 + header.len() + 1;
    header.push_str(&" ".repeat((64 - unpadded % 64) % 64));
    header.push('\n');
    let mut out = Vec::with_capacity(10 + header.len() + 4 * image.data().len());
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&[1, 0]);
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for v in image.data() {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

/// Writes an image as `.npy` (`<f4`, `[C, H, W]`, or `[H, W]` for one channel) atomically.
pub fn write_npy(path: &Path, image: &Image) -> Result<()> {
    if image.channels() == 0 || image.channels() > 4 {
        return Err(Error::invalid(
            format!("image for {}", path.display()),
            format!(
                ".npy images have 1..=4 channels, image has {}",
                image.channels()
            ),
        ));
    }
    let bytes = encode_npy(image);
    write_bytes_atomic(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A hand-made .npy file of the given version, header dict and payload.
    fn npy(major: u8, dict: &str, payload: &[u8]) -> Vec<u8> {
        let mut b = MAGIC.to_vec();
        b.extend_from_slice(&[major, 0]);
        let header = format!("{dict}\n");
        if major == 1 {
            b.extend_from_slice(&(header.len() as u16).to_le_bytes());
        } else {
            b.extend_from_slice(&(header.len() as u32).to_le_bytes());
        }
        b.extend_from_slice(header.as_bytes());
        b.extend_from_slice(payload);
        b
    }

    fn dec(b: &[u8]) -> Result<Image> {
        decode_npy(b, Path::new("t.npy"))
    }

    #[test]
    fn round_trip_f4() {
        let dir = tempfile::tempdir().unwrap();
        for c in [1, 3] {
            let p = dir.path().join(format!("a{c}.npy"));
            let im =
                Image::from_vec(c, 6, 5, (0..c * 30).map(|i| i as f32 * 0.5).collect()).unwrap();
            write_npy(&p, &im).unwrap();
            let bytes = std::fs::read(&p).unwrap();
            assert_eq!((bytes.len() - 4 * c * 30) % 64, 0);
            assert_eq!(read_npy(&p).unwrap(), im);
        }
    }

    #[test]
    fn dtypes_by_hand() {
        let u1 = npy(
            1,
            "{'descr': '|u1', 'fortran_order': False, 'shape': (1, 2), }",
            &[0, 255],
        );
        assert_eq!(dec(&u1).unwrap().data(), &[0.0, 1.0]);
        let mut p = Vec::new();
        for v in [0u16, 65535, 32768] {
            p.extend_from_slice(&v.to_be_bytes());
        }
        let u2 = npy(
            2,
            "{'descr': '>u2', 'fortran_order': False, 'shape': (3, 1), }",
            &p,
        );
        let im = dec(&u2).unwrap();
        assert_eq!(im.shape(), (1, 3, 1));
        assert_eq!(im.data()[..2], [0.0, 1.0]);
        let mut p = Vec::new();
        for v in [0.25f64, -3.0] {
            p.extend_from_slice(&v.to_le_bytes());
        }
        let f8 = npy(
            3,
            "{\"descr\": \"<f8\", \"fortran_order\": False, \"shape\": (2,1)}",
            &p,
        );
        assert_eq!(dec(&f8).unwrap().data(), &[0.25, -3.0]);
        let mut p = Vec::new();
        for v in [1.5f32, 2.5] {
            p.extend_from_slice(&v.to_be_bytes());
        }
        let f4 = npy(
            1,
            "{'descr': '>f4', 'fortran_order': False, 'shape': (1, 1, 2), }",
            &p,
        );
        let im = dec(&f4).unwrap();
        assert_eq!(im.shape(), (2, 1, 1), "[H, W, C] with C = 2");
        assert_eq!(im.data(), &[1.5, 2.5]);
    }

    #[test]
    fn channel_last_and_first() {
        // [H=1, W=2, C=3] interleaved -> planar.
        let hwc = npy(
            1,
            "{'descr': '|u1', 'fortran_order': False, 'shape': (1, 2, 3), }",
            &[0, 51, 102, 153, 204, 255],
        );
        let im = dec(&hwc).unwrap();
        assert_eq!(im.shape(), (3, 1, 2));
        assert_eq!(im.plane(0), &[0.0, 0.6]);
        // [C=2, H=3, W=5]: last dim 5 is not a channel count.
        let chw = npy(
            1,
            "{'descr': '|u1', 'fortran_order': False, 'shape': (2, 3, 5), }",
            &[0; 30],
        );
        assert_eq!(dec(&chw).unwrap().shape(), (2, 3, 5));
    }

    #[test]
    fn errors() {
        let e = |b: &[u8]| dec(b).unwrap_err().to_string();
        let f = npy(
            1,
            "{'descr': '<f4', 'fortran_order': True, 'shape': (1, 1), }",
            &[0; 4],
        );
        assert!(e(&f).contains("fortran_order"));
        let f = npy(
            1,
            "{'descr': '<i4', 'fortran_order': False, 'shape': (1, 1), }",
            &[0; 4],
        );
        assert!(e(&f).contains("<i4"));
        let f = npy(
            1,
            "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 2), }",
            &[0; 15],
        );
        assert!(e(&f).contains("truncated") && e(&f).contains("16"));
        let f = npy(
            1,
            "{'descr': '<f4', 'fortran_order': False, 'shape': (1, 1), }",
            &[0; 5],
        );
        assert!(e(&f).contains("oversized"));
        let f = npy(
            1,
            "{'descr': '<f4', 'fortran_order': False, 'shape': (7, 2, 2, 2), }",
            &[],
        );
        assert!(e(&f).contains("shape"));
        let f = npy(
            1,
            "{'descr': '<f4', 'fortran_order': False, 'shape': (6, 7, 8), }",
            &[],
        );
        assert!(e(&f).contains("shape"));
        assert!(e(b"PK\x03\x04zip").contains("magic"));
        let mut f = npy(
            1,
            "{'descr': '<f4', 'fortran_order': False, 'shape': (1, 1), }",
            &[],
        );
        f.truncate(20);
        assert!(e(&f).contains("header"));
    }

    #[test]
    fn empty_shapes_and_budget_are_refused() {
        // Fuzzing find: a shape with a zero side decoded to an empty image (Ok with no pixels).
        for shape in ["(0, 5)", "(5, 0)", "(0, 4, 4)", "(4, 4, 0)"] {
            let dict = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {shape}, }}");
            let e = dec(&npy(1, &dict, &[])).unwrap_err().to_string();
            assert!(e.contains("empty") && e.contains("t.npy"), "{shape}: {e}");
        }
        // A header declaring 16000x16000 is refused by the pixel budget, not by its length.
        let f = npy(
            1,
            "{'descr': '<f4', 'fortran_order': False, 'shape': (16000, 16000), }",
            &[],
        );
        let e = dec(&f).unwrap_err().to_string();
        assert!(
            e.contains("16000x16000") && e.contains("--max-pixels"),
            "{e}"
        );
    }
}
