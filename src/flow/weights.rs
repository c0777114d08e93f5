//! Weights files: safetensors holding the MMS parameters with the model config in the header's
//! metadata (`pins.model_config`), so a file alone is enough to rebuild and run the network.

use std::path::Path;

use burn::module::{Module, ModuleVisitor, Param};
use burn::prelude::*;
use burn::store::{ModuleSnapshot, SafetensorsStore};

use super::model::{Mms, MmsConfig};
use crate::error::{Error, Result};
use crate::io;

/// Metadata key of the model config.
pub const CONFIG_KEY: &str = "pins.model_config";

/// Number of scalar parameters of a module.
pub fn parameter_count<M: Module>(module: &M) -> usize {
    struct Count(usize);
    impl ModuleVisitor for Count {
        fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
            self.0 += p.val().shape().num_elements();
        }
    }
    let mut c = Count(0);
    module.visit(&mut c);
    c.0
}

/// Serialises `model` and its config to safetensors bytes.
pub fn to_bytes(model: &Mms, config: &MmsConfig) -> Result<Vec<u8>> {
    let json =
        serde_json::to_string(config).map_err(|e| Error::invalid("model config", e.to_string()))?;
    let mut store = SafetensorsStore::from_bytes(None).metadata(CONFIG_KEY, json);
    model
        .save_into(&mut store)
        .map_err(|e| Error::invalid("weights", format!("cannot serialise: {e}")))?;
    store
        .get_bytes()
        .map_err(|e| Error::invalid("weights", format!("cannot serialise: {e}")))
}

/// Writes `model` and its config to `path` atomically.
pub fn save(path: &Path, model: &Mms, config: &MmsConfig) -> Result<()> {
    io::write_bytes_atomic(path, &to_bytes(model, config)?)
}

/// The model config stored in a safetensors header.
pub fn read_config(bytes: &[u8], what: &Path) -> Result<MmsConfig> {
    let bad = |r: String| Error::format(what, format!("not a pins weights file: {r}"));
    if bytes.len() < 8 {
        return Err(bad("shorter than a safetensors header".into()));
    }
    let n = u64::from_le_bytes(bytes[..8].try_into().map_err(|_| bad("header".into()))?) as usize;
    if n > 100 << 20 || 8 + n > bytes.len() {
        return Err(bad(format!(
            "header of {n} bytes in a file of {}",
            bytes.len()
        )));
    }
    let header: serde_json::Value =
        serde_json::from_slice(&bytes[8..8 + n]).map_err(|e| bad(format!("header JSON: {e}")))?;
    let json = header
        .get("__metadata__")
        .and_then(|m| m.get(CONFIG_KEY))
        .and_then(|v| v.as_str())
        .ok_or_else(|| bad(format!("no {CONFIG_KEY} in the metadata")))?;
    let cfg: MmsConfig =
        serde_json::from_str(json).map_err(|e| bad(format!("model config: {e}")))?;
    cfg.validate()?;
    Ok(cfg)
}

/// Builds the network described by the bytes' config on `device` and loads its weights. Every
/// tensor must be present with its shape: a file of another config is an error.
pub fn from_bytes(bytes: &[u8], what: &Path, device: &Device) -> Result<(Mms, MmsConfig)> {
    let cfg = read_config(bytes, what)?;
    let mut model = Mms::new(&cfg, device);
    let mut store = SafetensorsStore::from_bytes(Some(bytes.to_vec()))
        .validate(true)
        .allow_partial(false);
    let applied = model.load_from(&mut store).map_err(|e| {
        Error::format(
            what,
            format!("weights do not fit the {} config: {e}", cfg.name),
        )
    })?;
    if !applied.errors.is_empty() || !applied.missing.is_empty() || !applied.unused.is_empty() {
        return Err(Error::format(
            what,
            format!(
                "weights do not fit the {} config: {} errors, {} missing and {} unused tensors",
                cfg.name,
                applied.errors.len(),
                applied.missing.len(),
                applied.unused.len()
            ),
        ));
    }
    Ok((model, cfg))
}

/// Loads a weights file.
pub fn load(path: &Path, device: &Device) -> Result<(Mms, MmsConfig)> {
    let bytes = io::read_bytes(path)?;
    from_bytes(&bytes, path, device)
}
