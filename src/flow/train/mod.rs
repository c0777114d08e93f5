//! Training the MMS network (Note S11).

pub mod budget;
pub mod checkpoint;
pub mod clip;
pub mod config;
pub mod cooldown;
pub mod log;
pub mod options;
pub mod param_ids;
pub mod prefetch;
pub mod resume;
pub mod save;
pub mod schedule;
pub mod setup;
pub mod source;
pub mod stamp;
pub mod step;
pub mod stream;
pub mod trainer;
pub mod validate;

pub use config::TrainConfig;
pub use options::{TrainOptions, TrainSummary};
pub use trainer::train;
