//! Is it a whole JPEG: the start-of-image marker first, the end-of-image marker last (padding
//! after it allowed), then a strict decode through the repository's image reader. A frame
//! that fails is skipped and counted, never processed.

use std::path::Path;

use crate::io::decode_image;
use crate::types::Image;

/// Why a part is not a usable frame.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Bad {
    Empty,
    NoStartMarker,
    /// No end-of-image marker: the usual truncated UXGA frame.
    Truncated,
    /// The markers are there but the decoder refused it.
    Corrupt(String),
}

impl std::fmt::Display for Bad {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Bad::Empty => write!(f, "empty part"),
            Bad::NoStartMarker => write!(f, "no JPEG start marker (FF D8)"),
            Bad::Truncated => write!(f, "truncated JPEG (no end marker FF D9)"),
            Bad::Corrupt(e) => write!(f, "corrupt JPEG: {e}"),
        }
    }
}

/// Bytes of padding (zeros, CR, LF, spaces) allowed after the end marker.
const MAX_PADDING: usize = 4096;

/// Checks the markers only (cheap).
pub fn check_markers(bytes: &[u8]) -> Result<(), Bad> {
    if bytes.is_empty() {
        return Err(Bad::Empty);
    }
    if !bytes.starts_with(&[0xFF, 0xD8]) {
        return Err(Bad::NoStartMarker);
    }
    let mut end = bytes.len();
    while end > 2
        && bytes.len() - end < MAX_PADDING
        && matches!(bytes[end - 1], 0 | b'\r' | b'\n' | b' ')
    {
        end -= 1;
    }
    if end < 4 || bytes[end - 2..end] != [0xFF, 0xD9] {
        return Err(Bad::Truncated);
    }
    Ok(())
}

/// Checks the markers and decodes the frame (`[C, H, W]` in [0, 1]).
pub fn decode_frame(bytes: &[u8]) -> Result<Image, Bad> {
    check_markers(bytes)?;
    decode_image(bytes, Path::new("frame.jpg")).map_err(|e| Bad::Corrupt(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn markers_are_checked() {
        assert_eq!(check_markers(b""), Err(Bad::Empty));
        assert_eq!(check_markers(b"\x89PNG"), Err(Bad::NoStartMarker));
        assert_eq!(check_markers(b"\xff\xd8\xff\xe0abc"), Err(Bad::Truncated));
        assert_eq!(check_markers(b"\xff\xd8abc\xff\xd9"), Ok(()));
        assert_eq!(check_markers(b"\xff\xd8abc\xff\xd9\0\0\r\n"), Ok(()));
        assert!(matches!(
            decode_frame(b"\xff\xd8abc\xff\xd9"),
            Err(Bad::Corrupt(_))
        ));
    }
}
