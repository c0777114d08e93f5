//! File formats: Middlebury .flo, PFM, KITTI PNG flow, EXR, .npy, images; atomic writes.
//!
//! Every writer goes through [`atomic::write_atomic`]: a failed write leaves no file behind.
//! Every reader returns an [`Error`](crate::Error) naming the path for malformed input, checks
//! the size a file declares against the pixel budget ([`budget`]) before decoding, and (for
//! flow) returns unknown vectors as NaN.

pub mod atomic;
pub mod budget;
pub mod chart;
pub mod exr;
pub mod flo;
pub mod flow_file;
pub mod image;
pub mod json;
pub mod kitti;
pub mod npy;
pub mod pfm;
pub mod python;
mod raster_guard;
pub mod unknown;

pub use atomic::{read_bytes, write_atomic, write_bytes_atomic};
pub use budget::{DEFAULT_MAX_PIXELS, max_pixels, set_max_pixels};
pub use exr::{decode_exr, decode_flow_exr, read_exr, read_flow_exr, write_exr, write_flow_exr};
pub use flo::{decode_flo, encode_flo, read_flo, write_flo};
pub use flow_file::{decode_flow, read_flow, write_flow};
pub use image::{
    BitDepth, decode_image, frame_files, image_files, read_capture, read_image, read_image_pair,
    write_image,
};
pub use json::{in_config, read_json};
pub use kitti::{decode_kitti_flow, read_kitti_flow, write_kitti_flow};
pub use npy::{decode_npy, read_npy, write_npy};
pub use pfm::{decode_pfm, decode_pfm_flow, read_pfm, read_pfm_flow, write_pfm, write_pfm_flow};
pub use unknown::is_unknown;

use std::path::Path;

/// The lower-cased extension of `path` (empty when there is none).
pub(crate) fn ext_lower(path: &Path) -> String {
    path.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default()
}
