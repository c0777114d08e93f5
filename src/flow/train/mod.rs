//! Training the MMS network (Note S11).

pub mod checkpoint;
pub mod clip;
pub mod config;
pub mod log;
pub mod param_ids;
pub mod schedule;
pub mod trainer;

pub use config::TrainConfig;
pub use trainer::{TrainOptions, TrainSummary, train};
