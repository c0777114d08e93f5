//! Resuming a run (Note S11 training in chunks): the run's config — the checkpoint's own, a
//! given one must equal it (each differing setting named) and `--steps` cannot change its
//! schedule — and its data, whose fingerprint must be the checkpoint's; a run that has taken
//! all its steps is reported as complete.

use super::checkpoint::{self, CheckpointState};
use super::config::TrainConfig;
use super::options::{TrainOptions, TrainSummary};
use crate::error::{Error, Result};
use crate::flow::data::DataFingerprint;
use crate::flow::model::{Mms, MmsConfig};
use crate::flow::weights;
use burn::prelude::*;

/// The config a run trains with, and the step it starts from: the stored one when resuming
/// (`given` must then equal it), `given` or the defaults for a new run; `--steps` applied and
/// the result validated.
pub fn run_config(
    given: Option<TrainConfig>,
    stored: Option<&CheckpointState>,
    opts: &TrainOptions,
) -> Result<(TrainConfig, usize)> {
    let (mut config, start) = match (stored, opts.resume) {
        (Some(state), true) => {
            if let Some(given) = &given {
                refuse_other_config(&state.config, given, opts)?;
            }
            (state.config.clone(), state.step)
        }
        (None, true) => {
            return Err(Error::invalid(
                "--resume",
                format!("{} has no checkpoint to resume", opts.out.display()),
            ));
        }
        (Some(_), false) => {
            return Err(Error::invalid(
                "--out",
                format!(
                    "{} already holds a run; pass --resume to continue it or choose another folder",
                    opts.out.display()
                ),
            ));
        }
        (None, false) => (given.unwrap_or_default(), 0),
    };
    if let Some(s) = opts.steps {
        if opts.resume && s != config.steps {
            return Err(Error::invalid(
                "--steps",
                format!(
                    "the run's schedule spans {} steps; resuming with {s} would change it",
                    config.steps
                ),
            ));
        }
        config.steps = s;
    }
    config.validate()?;
    Ok((config, start))
}

/// Refuses to resume on data other than the run's (when the checkpoint recorded its
/// fingerprint).
pub fn refuse_other_data(
    state: &CheckpointState,
    fingerprint: &DataFingerprint,
    opts: &TrainOptions,
) -> Result<()> {
    let Some(stored) = &state.data_fingerprint else {
        return Ok(());
    };
    if stored == fingerprint {
        return Ok(());
    }
    Err(Error::invalid(
        "--data",
        format!(
            "the run in {} was trained on {} ({} pairs, fingerprint {}), but {} holds {} \
             pairs (fingerprint {}): resuming on other data would silently change the run; \
             start a new run (--init with its weights to fine-tune)",
            opts.out.display(),
            state.data.display(),
            stored.pairs,
            &stored.sha256[..12.min(stored.sha256.len())],
            opts.data.display(),
            fingerprint.pairs,
            &fingerprint.sha256[..12],
        ),
    ))
}

/// What a run that has already taken all its steps reports: its stored state, nothing trained.
pub fn already_complete(state: &CheckpointState, model_config: &MmsConfig) -> TrainSummary {
    TrainSummary {
        steps: state.step,
        last_loss: state.last_loss,
        best_val_epe: state.best_val_epe,
        train_seconds: state.train_seconds,
        parameters: weights::parameter_count(&Mms::new(model_config, &Device::flex())),
        already_complete: true,
        pairs_seen: (state.step * state.config.batch_size) as u64,
        stopped: None,
    }
}

/// Refuses to resume with a config other than the run's, naming each setting that differs.
fn refuse_other_config(
    stored: &TrainConfig,
    given: &TrainConfig,
    opts: &TrainOptions,
) -> Result<()> {
    // `--steps` overrides the file's step count when the run starts; compare like with like.
    let mut given = given.clone();
    if let Some(s) = opts.steps {
        given.steps = s;
    }
    let diffs = checkpoint::config_differences(stored, &given);
    if diffs.is_empty() {
        return Ok(());
    }
    Err(Error::invalid(
        "--config",
        format!(
            "the run in {} was started with another config ({} → given): {}; resume without \
             --config (the run keeps its own) or start a new run",
            opts.out.display(),
            "checkpoint",
            diffs.join(", ")
        ),
    ))
}
