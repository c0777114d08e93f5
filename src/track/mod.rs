//! Motion trajectory prediction from flow (Notes S13–S15): regions of interest, Kalman
//! smoothing, weighted polynomial fits and sub-step extrapolation, optimal assignment.

pub mod eval;
pub mod experiment;
pub mod hungarian;
pub mod kalman;
pub mod mtp;
pub mod multi;
pub mod predict;
pub mod roi;
pub mod run;
