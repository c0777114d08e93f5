//! File formats: Middlebury .flo, PFM, KITTI PNG flow, EXR, .npy, images; atomic writes.

pub mod atomic;

pub use atomic::{read_bytes, write_atomic, write_bytes_atomic};
