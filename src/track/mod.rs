//! Motion trajectory prediction from flow (Notes S13–S15): regions of interest confirmed by a
//! background-motion model, a photometric test and consistency over frames, Kalman smoothing,
//! weighted polynomial fits and sub-step extrapolation, optimal assignment.

pub mod align;
pub mod appearance;
pub mod associate;
pub mod background;
pub mod change;
pub mod config;
pub mod consistency;
pub mod coverage;
pub mod detect;
pub mod eval;
pub mod experiment;
pub mod forecast_score;
pub mod foreground;
pub mod grow;
pub mod hungarian;
pub mod kalman;
pub mod mtp;
pub mod multi;
pub mod noise_floor;
pub mod noise_level;
pub mod photometric;
pub mod placement;
pub mod points;
pub mod predict;
pub mod reid;
pub mod retry;
pub mod roi;
pub mod run;
pub mod split;
pub mod static_flow;
pub mod still_background;
pub mod tracker_config;
pub mod trim;
