//! The dataset generator: deterministic per-sample seeds, sharding, parallel, resumable.

pub mod config;
pub mod generate;
pub mod manifest;
pub mod sequence;

pub use config::{GeneratorConfig, SceneSpec};
pub use generate::{Generator, RunSummary, Shard};
pub use manifest::{Manifest, SampleMeta};
