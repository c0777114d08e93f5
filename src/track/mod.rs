//! Motion trajectory prediction from flow (Notes S13–S15), by stage as SORT, ByteTrack and
//! OC-SORT read; data flows one way and a stage imports only from the stages before it:
//!
//! - `detect/`: regions of interest confirmed by a background-motion model, the change and
//!   photometric tests, the alignment and the placement on the frame.
//! - `motion/`: Kalman smoothing, weighted polynomial fits, sub-step extrapolation, forecasts.
//! - `tracker/`: association (optimal assignment), track life, re-identification, the tracks.
//! - `eval/`: RMSE per horizon (Table S5), ID switches, coverage, operating points.
//!
//! Above the stages, and free to import from all of them: `config.rs` (the one `TrackConfig`),
//! `run.rs` (the sequence runner that ties the stages together) and `experiment.rs` (clips ×
//! predictors, tracked and scored). `robust.rs`, the median, MAD and robust standard
//! deviation every stage reads, imports nothing.

pub mod config;
pub mod detect;
pub mod eval;
pub mod experiment;
pub mod motion;
pub mod robust;
pub mod run;
pub mod tracker;
