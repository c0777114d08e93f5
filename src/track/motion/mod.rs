//! Stage 2, motion (Note S13, Fig. S11, Eqs. S20–S23): one object's regions become a smoothed
//! state and forecasts at every horizon. It imports only from `detect` (a region is its
//! measurement). Its files:
//!
//! - `kalman.rs`: the Kalman filters (constant velocity, random walk; Joseph form).
//! - `predict.rs`: the weighted polynomial fit of speed and direction, sub-step extrapolation.
//! - `forecast_score.rs`: each candidate forecast's record against where the track went.
//! - `mtp.rs`: one object's motion trajectory predictor, its settings and its estimate.
//! - `step.rs`: a processed frame's time and its flow's span on a stream processed at uneven
//!   gaps.

pub mod forecast_score;
pub mod kalman;
pub mod mtp;
pub mod predict;
pub mod step;
