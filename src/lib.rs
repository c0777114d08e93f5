//! `pins`: metalens motion sensing, from the supplementary notes S1–S17 of the PINS paper.
//!
//! | module | what (paper) |
//! |---|---|
//! | [`types`] | core `Image` `[C, H, W]` and `Flow` `[2, H, W]` |
//! | [`error`] | the one `Error` enum |
//! | [`rng`] | deterministic seeding by (seed, purpose, index) |
//! | [`io`] | file formats (.flo, PFM, KITTI PNG, EXR, .npy, images), atomic writes |
//! | [`optics`] | Note S2 (phase profiles, PSF), S6 (depth of field), S12, S17 |
//! | [`imaging`] | Notes S4–S5: brightness, PSF convolution, noise (Eqs. S1–S3), gamma (Eq. S4) |
//! | [`scene`] | layered moving scenes with exact flow, Note S12 test patterns, dataset readers |
//! | [`dataset`] | the generator of image pairs with ground-truth flow |
//! | [`flow`] | optical flow with the MMS network (Notes S9–S11) |
//! | [`flow::model`] | the network as the paper reads it: DSMSCE encoders (Eqs. S13–S15), correlation pyramid and lookup, ConvGRU (Eqs. S9–S12) in `model/gru.rs`, convex upsampling |
//! | [`flow::ops`] | one entry per heavy operation; the choice between host kernels and Burn in `ops/route.rs`; autodiff `Backward`s |
//! | [`flow::kernels`] | the CPU mathematics on `&[f32]` (the convolution in `kernels/conv.rs`); `unsafe`, gemm and rayon only here |
//! | [`flow::sequence`] | MMS over consecutive frames (`infer --frames`, `track --frames`, experiments) |
//! | [`flow::train`] | training: sequence loss (Eq. S16), AdamW, one-cycle, checkpoints (Note S11) |
//! | [`flow::data`], [`flow::eval`], [`flow::metrics`], [`flow::infer`], [`flow::weights`], [`flow::loss`], [`flow::viz`], [`flow::device`] | data loading, evaluation (Table S4), metrics, inference, weights files, Eq. S16, colour wheel, device choice |
//! | [`wide`] | Notes S2, S3, S16: the 3-lens array, calibration, stitching to 135° |
//! | [`track`] | Notes S13–S15: ROI, Kalman, polynomial fits, extrapolation, multi-object IDs (Table S5) |
//! | [`live`] | Note S1: the ESP32 camera's MJPEG stream, recording/replay, the live pipeline and its browser view |
//! | [`report`] | benchmarks, tables and plots; the real-data benchmark, Note S12's detection limits |

pub mod dataset;
pub mod error;
pub mod flow;
pub mod imaging;
pub mod io;
pub mod live;
pub mod optics;
pub mod report;
pub mod rng;
pub mod scene;
pub mod track;
pub mod types;
pub mod wide;

pub use error::{Error, Result};
pub use types::{Flow, Image};
