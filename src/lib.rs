//! `pins`: metalens motion sensing, from the supplementary notes S1–S17 of the PINS paper.
//!
//! | module | paper |
//! |---|---|
//! | [`types`] | core `Image` `[C, H, W]` and `Flow` `[2, H, W]` |
//! | [`io`] | file formats (.flo, PFM, KITTI PNG, EXR, .npy, images), atomic writes |
//! | [`optics`] | Note S2 (phase profiles, PSF), S6 (depth of field), S12, S17 |
//! | [`imaging`] | Notes S4–S5: brightness, PSF convolution, noise (Eqs. S1–S3), gamma (Eq. S4) |
//! | [`scene`] | layered moving scenes with exact flow, Note S12 test patterns, dataset readers |
//! | [`dataset`] | the generator of image pairs with ground-truth flow |
//! | [`report`] | benchmarks and tables |

pub mod dataset;
pub mod error;
pub mod flow;
pub mod imaging;
pub mod io;
pub mod optics;
pub mod report;
pub mod report_timing;
pub mod rng;
pub mod scene;
pub mod track;
pub mod types;
pub mod wide;

pub use error::{Error, Result};
pub use types::{Flow, Image};
