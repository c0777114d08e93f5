//! Stage 4, evaluation (Note S15, Table S5): tracks scored against the truth. It imports from
//! the stages before it (the tracks, the Hungarian matching, the background-flow magnitude)
//! and from none after. Its files:
//!
//! - `rmse.rs`: each track matched to one object; RMSE_X, RMSE_Y, RMSE_2D per horizon, ID
//!   switches, the report and its table (`evaluate`, `TrackReport`).
//! - `coverage.rs`: MOTChallenge's coverage (mostly tracked, partially, lost) and IDF1.
//! - `points.rs`: the operating points, error against run time per frame, table and chart.

pub mod coverage;
pub mod points;
pub mod rmse;

pub use rmse::{HorizonError, ObjectReport, TrackReport, evaluate, table};
