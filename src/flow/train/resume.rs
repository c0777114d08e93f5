//! Resuming a run (Note S11 training in chunks): the run's config — the checkpoint's own, a
//! given one must equal it (each differing setting named) and `--steps` cannot change its
//! schedule — and its data, whose fingerprint must be the checkpoint's; a run that has taken
//! all its steps is reported as complete. A branch (`--branch-from`) starts a new folder from
//! another run's checkpoint, as a resume would; a cool-down ([`super::cooldown`]) is fixed when
//! it starts and kept by every resume after, and a new one may anneal on other data.

use super::checkpoint::{self, CheckpointState, Loaded};
use super::config::TrainConfig;
use super::cooldown::Cooldown;
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
    let resuming = opts.resume || opts.branch_from.is_some();
    let (mut config, start) = match (stored, resuming) {
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
        if resuming && s != config.steps {
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

/// The checkpoint a session starts from: that of the run in `--out`, or for a branch that of
/// the run it branches from (`--out` must then hold no run yet).
pub fn existing(opts: &TrainOptions) -> Result<Option<Loaded>> {
    let Some(trunk) = &opts.branch_from else {
        return checkpoint::read(&opts.out);
    };
    let conflict = [
        ("--resume", opts.resume),
        ("--init", opts.init.is_some()),
        ("--continue-from", opts.continue_from.is_some()),
    ]
    .into_iter()
    .find(|(_, given)| *given);
    if let Some((flag, _)) = conflict {
        return Err(Error::invalid(
            "--branch-from",
            format!("cannot be combined with {flag} (the branch starts from the run's checkpoint)"),
        ));
    }
    if checkpoint::dir(&opts.out).join("state.json").exists() {
        return Err(Error::invalid(
            "--out",
            format!(
                "{} already holds a run; a branch starts in a new folder (continue this one \
                 with --resume)",
                opts.out.display()
            ),
        ));
    }
    match checkpoint::read(trunk)? {
        Some(loaded) => Ok(Some(loaded)),
        None => Err(Error::invalid(
            "--branch-from",
            format!("{} has no checkpoint to branch from", trunk.display()),
        )),
    }
}

/// The cool-down a session trains under: the checkpoint's (a resume keeps it; `--cooldown`
/// may repeat it but not change it), or a new one of `--cooldown` steps from `start`, the
/// step the run stands at. Only a run with a checkpoint behind it cools down (a resume or a
/// branch): a new run has no stable phase to end.
pub fn cooldown(
    stored: Option<&CheckpointState>,
    config: &TrainConfig,
    start: usize,
    opts: &TrainOptions,
) -> Result<Option<Cooldown>> {
    let kept = stored.and_then(|s| s.cooldown);
    match (kept, opts.cooldown) {
        (kept, None) => Ok(kept),
        (Some(c), Some(n)) if c.steps == n => Ok(Some(c)),
        (Some(c), Some(n)) => Err(Error::invalid(
            "--cooldown",
            format!(
                "the run in {} is cooling down over {} steps from step {}; it cannot change \
                 to {n}",
                opts.out.display(),
                c.steps,
                c.start
            ),
        )),
        (None, Some(n)) => {
            // With a checkpoint, `run_config` has already required --resume or --branch-from.
            if stored.is_none() {
                return Err(Error::invalid(
                    "--cooldown",
                    "needs a run to cool down: --resume (this run) or --branch-from RUN",
                ));
            }
            Cooldown::new(start, n, config.steps).map(Some)
        }
    }
}

/// The data a session trains on, against the run's (when the checkpoint recorded its
/// fingerprint): a resume must train on the run's data. A new cool-down branch
/// (`--branch-from` with `--cooldown`) may anneal on other data, as warmup–stable–decay
/// schedules end on a mix of their own: the branch's checkpoint and weights then record the
/// data it cooled down on, and the line returned says which it left.
pub fn check_data(
    state: &CheckpointState,
    fingerprint: &DataFingerprint,
    opts: &TrainOptions,
) -> Result<Option<String>> {
    let Some(stored) = &state.data_fingerprint else {
        return Ok(None);
    };
    if stored == fingerprint {
        return Ok(None);
    }
    let new_cooldown = opts.branch_from.is_some() && opts.cooldown.is_some();
    if new_cooldown && state.cooldown.is_none() {
        return Ok(Some(format!(
            "the cool-down anneals on {} ({}), not on the run's {} ({})",
            opts.data.display(),
            fingerprint.describe(),
            state.data.display(),
            stored.describe(),
        )));
    }
    Err(Error::invalid(
        "--data",
        format!(
            "the run in {} was trained on {} ({}), but {} holds {}: resuming on other \
             data would silently change the run; start a new run (--init with its weights to \
             fine-tune), or cool a branch down on it (--branch-from with --cooldown)",
            opts.branch_from.as_ref().unwrap_or(&opts.out).display(),
            state.data.display(),
            stored.describe(),
            opts.data.display(),
            fingerprint.describe(),
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
        other_data: None,
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
