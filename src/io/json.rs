//! JSON configs and reports: read a file into a typed value whose errors name the file and the
//! offending key or value (unknown keys are rejected by the types themselves).

use std::path::Path;

use serde::de::DeserializeOwned;

use crate::error::{Error, Result};

/// Reads the JSON file at `path` into `T`.
pub fn read_json<T: DeserializeOwned>(path: &Path) -> Result<T> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    serde_json::from_str(&text).map_err(|e| in_config(path, e))
}

/// An error found in the config file at `path` (a parse error, or a value out of range).
pub fn in_config(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::Config {
        path: path.to_path_buf(),
        reason: e.to_string(),
    }
}
