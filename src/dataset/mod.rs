//! The dataset generator: deterministic per-sample seeds, sharding, parallel, resumable.
