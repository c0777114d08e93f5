//! The wide-angle metalens array (Notes S2, S3, S16): layout, lens mapping, raw frames,
//! calibration from dot grids, stitching to one 135° image.

pub mod calibrate;
pub mod layout;
pub mod polyfit;
pub mod projection;
pub mod render;
pub mod stitch;

pub use calibrate::{Calibration, calibrate};
pub use layout::ArrayLayout;
pub use stitch::Stitcher;
