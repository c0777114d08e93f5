//! The MMS network (Notes S9–S10) in Burn.

pub mod act;
pub mod blocks;
pub mod config;
pub mod corr;
pub mod corr_lookup_op;
pub mod encoder;
pub mod flex_bridge;
pub mod host_conv;
pub mod host_norm;
pub mod mms;
pub mod padder;
mod shifted_conv;
pub mod train_conv;
pub mod train_norm;
pub mod update;
pub mod upsample;
pub mod upsample_host;
mod vexp;

pub use config::{MmsConfig, NormKind};
pub use mms::Mms;
pub use padder::InputPadder;
