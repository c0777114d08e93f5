//! JSON configs and reports: read a file into a typed value whose errors name the file and the
//! offending key or value (unknown keys are rejected by the types themselves).

use std::path::Path;

use serde::Deserialize;
use serde::de::DeserializeOwned;

use crate::error::{Error, Result};

/// Reads the JSON file at `path` into `T`.
pub fn read_json<T: DeserializeOwned>(path: &Path) -> Result<T> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    serde_json::from_str(&text).map_err(|e| in_config(path, e))
}

/// A number that may be NaN in a report (an error over no predictions): JSON has no NaN and
/// serde_json writes it as `null`, which this reads back as NaN, so a report round-trips
/// (`#[serde(deserialize_with = "nan_if_null")]`).
pub fn nan_if_null<'de, D: serde::Deserializer<'de>>(d: D) -> std::result::Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}

/// An error found in the config file at `path` (a parse error, or a value out of range).
pub fn in_config(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::Config {
        path: path.to_path_buf(),
        reason: e.to_string(),
    }
}
