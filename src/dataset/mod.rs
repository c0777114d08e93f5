//! The dataset generator: deterministic per-sample seeds, sharding, parallel, resumable, with
//! every file's size and SHA-256 recorded, an atomic claim on the output folder, and `--verify`.

pub mod config;
pub mod folder;
pub mod generate;
pub mod integrity;
pub mod manifest;
pub mod scheduler;
pub mod sequence;
pub mod shards;
pub mod verify;

pub use config::{GeneratorConfig, SceneSpec};
pub use generate::{Generator, RunSummary, Shard};
pub use manifest::{FileRecord, Manifest, SampleMeta};
pub use verify::{VerifyReport, verify};
