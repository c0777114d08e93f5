//! Saving a run after a step: the checkpoint (network, optimiser, and the state with the
//! config and data fingerprints that `--resume` checks), `last.safetensors` and the curves.

use burn::prelude::*;

use super::checkpoint::{self, CheckpointState};
use super::config::TrainConfig;
use super::setup::{Run, record_error};
use super::trainer::TrainOptions;
use crate::error::Result;
use crate::flow::data::DataFingerprint;
use crate::flow::model::MmsConfig;
use crate::flow::weights;

/// Writes the checkpoint of `run` after `step` steps, its exported weights and its curves.
pub fn save(
    run: &Run,
    config: &TrainConfig,
    model_config: &MmsConfig,
    step: usize,
    fingerprint: &DataFingerprint,
    opts: &TrainOptions,
) -> Result<()> {
    let model_bytes = run
        .model
        .clone()
        .into_record()
        .into_bytes()
        .map_err(|e| record_error("checkpoint model", e))?;
    let optim_bytes = run
        .optim
        .into_bytes()
        .map_err(|e| record_error("checkpoint optimiser", e))?;
    let state = CheckpointState {
        step,
        model_file: format!("model-{step:07}.bpk"),
        optimizer_file: format!("optim-{step:07}.bin"),
        config: config.clone(),
        config_sha256: Some(checkpoint::config_sha256(config)?),
        data: opts.data.clone(),
        data_fingerprint: Some(fingerprint.clone()),
        best_val_epe: run.best_val,
        last_loss: run.last_loss,
        train_seconds: run.seconds,
    };
    checkpoint::write(&opts.out, &state, &model_bytes, &optim_bytes)?;
    weights::save(
        &opts.out.join("last.safetensors"),
        &run.model.valid(),
        model_config,
    )?;
    run.log.plot(&opts.out.join("curves.png"))
}
