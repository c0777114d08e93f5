//! Optical flow: the MMS network (Notes S9–S11), training, export, inference, evaluation,
//! metrics and visualisation.

pub mod average;
pub mod data;
pub mod device;
pub mod dis;
pub mod eval;
pub mod infer;
pub mod iters;
pub mod kernels;
pub mod loss;
pub mod metrics;
pub mod model;
pub mod ops;
pub mod refine;
pub mod resample;
pub mod scale;
pub mod sequence;
pub mod train;
pub mod video;
pub mod viz;
pub mod warm;
pub mod weights;
