//! Saving a run after a step: the checkpoint (network, optimiser, and the state with the
//! config and data fingerprints that `--resume` checks), `last.safetensors` (with its training
//! stamp, from which `--continue-from` goes on), a snapshot of it where asked, and the curves.

use burn::prelude::*;

use super::checkpoint::{self, CheckpointState};
use super::config::TrainConfig;
use super::cooldown::Cooldown;
use super::options::TrainOptions;
use super::setup::{Run, record_error};
use super::stamp::TrainingStamp;
use crate::error::{Error, Result};
use crate::flow::data::DataFingerprint;
use crate::flow::model::MmsConfig;
use crate::flow::weights;
use crate::io;

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
        restart_step: run.restart,
        cooldown: run.cooldown,
    };
    checkpoint::write(&opts.out, &state, &model_bytes, &optim_bytes)?;
    let last = weights::to_bytes_with(
        &run.model.valid(),
        model_config,
        &[stamp(config, step, fingerprint, run.cooldown).entry()?],
    )?;
    io::write_bytes_atomic(&opts.out.join("last.safetensors"), &last)?;
    if let Some(dir) = &opts.snapshots {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        io::write_bytes_atomic(&dir.join(format!("step-{step:07}.safetensors")), &last)?;
    }
    run.log.plot(&opts.out.join("curves.png"))
}

/// The training stamp of a run's weights after `step` steps on the data of `fingerprint`, in
/// its cool-down if it has one.
pub fn stamp(
    config: &TrainConfig,
    step: usize,
    fingerprint: &DataFingerprint,
    cooldown: Option<Cooldown>,
) -> TrainingStamp {
    TrainingStamp {
        step,
        steps: config.steps,
        pairs_seen: (step * config.batch_size) as u64,
        config: config.clone(),
        data: fingerprint.clone(),
        cooldown,
    }
}
