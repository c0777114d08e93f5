//! Checkpoints: model and optimiser state written under step-numbered names, then `state.json`
//! (written last, atomically) points at them, so an interrupted write never replaces the last
//! good checkpoint.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::config::TrainConfig;
use super::cooldown::Cooldown;
use crate::error::{Error, Result};
use crate::flow::data::DataFingerprint;
use crate::io;

/// What `state.json` records.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CheckpointState {
    /// Steps completed.
    pub step: usize,
    pub model_file: String,
    pub optimizer_file: String,
    pub config: TrainConfig,
    /// SHA-256 of the config's JSON: a resume with another config is refused.
    #[serde(default)]
    pub config_sha256: Option<String>,
    pub data: PathBuf,
    /// The training data's fingerprint: a resume on other data is refused.
    #[serde(default)]
    pub data_fingerprint: Option<DataFingerprint>,
    pub best_val_epe: Option<f64>,
    /// Loss of the last step taken.
    #[serde(default)]
    pub last_loss: Option<f64>,
    /// Wall-clock seconds of training so far, over all sessions.
    pub train_seconds: f64,
    /// The step at which the run was warm-restarted from weights alone (`--continue-from`),
    /// whose learning-rate warm-up a resume must repeat.
    #[serde(default)]
    pub restart_step: Option<usize>,
    /// The cool-down the run ends with, if it has one (a resume keeps it).
    #[serde(default)]
    pub cooldown: Option<Cooldown>,
}

/// SHA-256 (hex) of a config's JSON, the key order being the struct's.
pub fn config_sha256(config: &TrainConfig) -> Result<String> {
    use sha2::{Digest, Sha256};
    let json = serde_json::to_vec(config).map_err(|e| Error::invalid("config", e.to_string()))?;
    let digest = Sha256::digest(&json);
    Ok(digest.iter().map(|b| format!("{b:02x}")).collect())
}

/// The settings in which `given` differs from `stored`, as `key: stored → given` lines (nested
/// keys joined with dots), in the config's key order.
pub fn config_differences(stored: &TrainConfig, given: &TrainConfig) -> Vec<String> {
    fn walk(prefix: &str, a: &serde_json::Value, b: &serde_json::Value, out: &mut Vec<String>) {
        match (a, b) {
            (serde_json::Value::Object(x), serde_json::Value::Object(y)) => {
                for (k, va) in x {
                    let key = if prefix.is_empty() {
                        k.clone()
                    } else {
                        format!("{prefix}.{k}")
                    };
                    match y.get(k) {
                        Some(vb) => walk(&key, va, vb, out),
                        None => out.push(format!("{key}: {va} → (absent)")),
                    }
                }
            }
            _ if a != b => out.push(format!("{prefix}: {a} → {b}")),
            _ => {}
        }
    }
    let (Ok(a), Ok(b)) = (serde_json::to_value(stored), serde_json::to_value(given)) else {
        return vec!["(the configs cannot be compared)".into()];
    };
    let mut out = Vec::new();
    walk("", &a, &b, &mut out);
    out
}

/// The checkpoint folder of a run.
pub fn dir(run: &Path) -> PathBuf {
    run.join("checkpoint")
}

/// Writes a checkpoint: `model-STEP.bpk`, `optim-STEP.bin`, then `state.json`; removes the
/// files of older steps afterwards.
pub fn write(run: &Path, state: &CheckpointState, model: &[u8], optimizer: &[u8]) -> Result<()> {
    let d = dir(run);
    io::write_bytes_atomic(&d.join(&state.model_file), &canonical_burnpack(model)?)?;
    io::write_bytes_atomic(
        &d.join(&state.optimizer_file),
        &canonical_burnpack(optimizer)?,
    )?;
    let json = serde_json::to_string_pretty(state)
        .map_err(|e| Error::invalid("checkpoint", e.to_string()))?;
    io::write_bytes_atomic(&d.join("state.json"), json.as_bytes())?;
    for entry in std::fs::read_dir(&d)
        .map_err(|e| Error::io(&d, e))?
        .flatten()
    {
        let name = entry.file_name().to_string_lossy().into_owned();
        if (name.starts_with("model-") || name.starts_with("optim-"))
            && name != state.model_file
            && name != state.optimizer_file
        {
            let _ = std::fs::remove_file(entry.path());
        }
    }
    Ok(())
}

/// The same burnpack content with its tensors in name order. Burn writes the optimiser's state
/// from a hash map, so the same state could otherwise give different files; metadata and
/// scalars are already sorted maps.
pub fn canonical_burnpack(bytes: &[u8]) -> Result<Vec<u8>> {
    use burn::store::burn_pack::{Bytes, Reader, Writer};
    let bad = |e: &dyn std::fmt::Display| Error::invalid("checkpoint", format!("burnpack: {e}"));
    let reader = Reader::from_bytes(Bytes::from_bytes_vec(bytes.to_vec())).map_err(|e| bad(&e))?;
    let metadata = reader.metadata().clone();
    let scalars = reader.scalars().clone();
    let mut tensors = reader.into_tensors().map_err(|e| bad(&e))?;
    tensors.sort_by(|a, b| a.name.cmp(&b.name));
    let mut writer = Writer::new(tensors);
    for (k, v) in &metadata {
        writer = writer.with_metadata(k, v);
    }
    for (k, v) in &scalars {
        writer = writer.with_scalar(k, *v);
    }
    Ok(writer.into_bytes().map_err(|e| bad(&e))?.to_vec())
}

/// A checkpoint read back: its state, the model bytes and the optimiser bytes.
pub type Loaded = (CheckpointState, Vec<u8>, Vec<u8>);

/// Reads the last checkpoint of `run`, if any.
pub fn read(run: &Path) -> Result<Option<Loaded>> {
    let p = dir(run).join("state.json");
    if !p.exists() {
        return Ok(None);
    }
    let text = std::fs::read_to_string(&p).map_err(|e| Error::io(&p, e))?;
    let state: CheckpointState =
        serde_json::from_str(&text).map_err(|e| Error::format(&p, e.to_string()))?;
    let model = io::read_bytes(&dir(run).join(&state.model_file))?;
    let optim = io::read_bytes(&dir(run).join(&state.optimizer_file))?;
    Ok(Some((state, model, optim)))
}
