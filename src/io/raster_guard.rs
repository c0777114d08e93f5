//! Cheap checks of raster headers that the `image` crate's decoders trust too much, run before
//! they see the bytes: a TIFF directory entry whose values would lie beyond the end of the file.
//!
//! The `tiff` crate reserves memory for an entry's declared value count before reading it (up to
//! 256 MiB), and it does so while the decoder is being built, before any limit can be set; a
//! 400-byte file could make it reserve 268 MB. An entry's values must lie inside the file, so
//! an entry that claims more than that is refused here, with its tag and sizes.

use std::path::Path;

use crate::error::{Error, Result};

/// Checks the entries of the first image directory of a TIFF (classic or BigTIFF) file: the
/// values of each must fit inside the file. Other content passes untouched (the decoder judges
/// it), as do entries that are themselves cut off by the end of the file.
pub(crate) fn check_tiff(bytes: &[u8], path: &Path) -> Result<()> {
    let little = match bytes.get(..2) {
        Some(b"II") => true,
        Some(b"MM") => false,
        _ => return Ok(()),
    };
    let int = |at: usize, n: usize| -> Option<u64> {
        let b = bytes.get(at..at.checked_add(n)?)?;
        let mut v = 0u64;
        for i in 0..n {
            let byte = if little { b[n - 1 - i] } else { b[i] };
            v = (v << 8) | u64::from(byte);
        }
        Some(v)
    };
    // (entry count width, entry size, count width, inline value width, first IFD offset)
    let (count_w, entry_w, n_w, inline_w, ifd) = match int(2, 2) {
        Some(42) => (2, 12, 4, 4, int(4, 4)),
        Some(43) => (8, 20, 8, 8, int(8, 8)),
        _ => return Ok(()),
    };
    let Some(ifd) = ifd.and_then(|v| usize::try_from(v).ok()) else {
        return Ok(());
    };
    let Some(entries) = int(ifd, count_w) else {
        return Ok(());
    };
    let len = bytes.len() as u64;
    for i in 0..entries {
        let Some(at) = usize::try_from(i)
            .ok()
            .and_then(|i| i.checked_mul(entry_w))
            .and_then(|o| o.checked_add(ifd + count_w))
        else {
            break;
        };
        let (Some(tag), Some(kind), Some(count), Some(offset)) = (
            int(at, 2),
            int(at + 2, 2),
            int(at + 4, n_w),
            int(at + 4 + n_w, inline_w),
        ) else {
            break;
        };
        let size = u128::from(count) * u128::from(type_size(kind));
        if size <= inline_w as u128 {
            continue;
        }
        if u128::from(offset) + size > u128::from(len) {
            return Err(Error::format(
                path,
                format!(
                    "TIFF tag {tag} declares {count} values of type {kind} ({size} bytes) at \
                     offset {offset}, beyond the end of the {len}-byte file"
                ),
            ));
        }
    }
    Ok(())
}

/// Bytes per value of a TIFF field type (unknown types count as 1, a lower bound).
fn type_size(kind: u64) -> u64 {
    match kind {
        3 | 8 => 2,
        4 | 9 | 11 | 13 => 4,
        5 | 10 | 12 | 16..=18 => 8,
        _ => 1,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A little-endian classic TIFF whose one entry declares `count` SHORTs at `offset`.
    fn tiff(count: u32, offset: u32, len: usize) -> Vec<u8> {
        let mut b = b"II*\0".to_vec();
        b.extend_from_slice(&8u32.to_le_bytes());
        b.extend_from_slice(&1u16.to_le_bytes());
        b.extend_from_slice(&258u16.to_le_bytes());
        b.extend_from_slice(&3u16.to_le_bytes());
        b.extend_from_slice(&count.to_le_bytes());
        b.extend_from_slice(&offset.to_le_bytes());
        b.resize(len, 0);
        b
    }

    #[test]
    fn entry_beyond_the_file_is_refused() {
        // Reproducer of the fuzzing find: a tag claiming 0x7fff_0000 values in a tiny file.
        let e = check_tiff(&tiff(0x7fff_0000, 22, 400), Path::new("t.tif"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("t.tif") && e.contains("tag 258") && e.contains("400-byte"),
            "{e}"
        );
        // Values inside the file, or inline, pass; so does anything that is not a TIFF.
        assert!(check_tiff(&tiff(100, 22, 400), Path::new("t.tif")).is_ok());
        assert!(check_tiff(&tiff(2, 0xffff_ffff, 30), Path::new("t.tif")).is_ok());
        assert!(check_tiff(&tiff(190, 22, 400), Path::new("t.tif")).is_err());
        assert!(check_tiff(b"\x89PNG", Path::new("p.png")).is_ok());
        // Cut-off directories are left to the decoder.
        assert!(check_tiff(&tiff(0x7fff_0000, 22, 400)[..12], Path::new("t.tif")).is_ok());
    }

    #[test]
    fn decoding_such_a_file_is_a_typed_error() {
        let e = crate::io::decode_image(&tiff(0x7fff_0000, 22, 400), Path::new("t.tif"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("beyond the end"), "{e}");
    }
}
