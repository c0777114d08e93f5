//! `pins train`: the MMS network on a generated dataset, or on pairs made on the fly
//! ([`super::stream`]), with the sequence loss of Eq. S16,
//! AdamW, the one-cycle schedule and global gradient clipping; held-out validation on a
//! schedule; atomic checkpoints from which `--resume` continues exactly (same step, optimiser
//! state, schedule and data order); a CSV log and a PNG plot of the curves. A session ends at
//! its last step, at `--stop-after`, before the step (and its validation) that would pass
//! `--time-budget` (the last ones' durations are the estimate), or at the
//! step after a stop request (SIGTERM), each time with a checkpoint; one is written at least
//! every ten minutes besides. `--continue-from` goes on from a weights file's training stamp
//! when the checkpoint is gone (a warm restart, [`super::stamp`]); `--cooldown` ends a run, or a
//! branch of it (`--branch-from`), by taking the rate to zero ([`super::cooldown`]).
//!
//! This file is the loop; its parts are [`super::resume`] (the run's config and the checks
//! against a checkpoint), [`super::setup`] (network, optimiser, run folder), [`super::step`],
//! [`super::validate`], [`super::save`] (checkpoints) and [`super::log`].

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use burn::prelude::*;
use indicatif::{ProgressBar, ProgressStyle};

use super::budget::Budget;
use super::config::TrainConfig;
use super::log::LogRow;
use super::options::{TrainOptions, TrainSummary};
use super::prefetch::Prefetch;
use super::schedule::one_cycle;
use super::setup::WarmRestart;
use super::source::TrainData;
use super::stamp::{TrainingStamp, restart_factor};
use super::{checkpoint, cooldown};
use super::{resume, save, setup, step, validate};
use crate::error::{Error, Result};
use crate::flow::data::DataFingerprint;

/// Trains (or resumes) a run. `config` is the run's config: required to be equal to the stored
/// one when resuming (`None` then means "the stored one"), the defaults when `None` on a new run.
pub fn train(config: Option<TrainConfig>, opts: &TrainOptions) -> Result<TrainSummary> {
    let budget = Budget::new(opts.time_budget, opts.stop.clone());
    let existing = resume::existing(opts)?;
    let (config, mut start) = resume::run_config(config, existing.as_ref().map(|e| &e.0), opts)?;
    let cooldown = resume::cooldown(existing.as_ref().map(|e| &e.0), &config, start, opts)?;
    // Where the run ends: its schedule's last step, or its cool-down's.
    let end = cooldown.map_or(config.steps, |c| c.end());
    let model_config = config.model_config()?;
    let data = TrainData::open(&opts.data, &config)?;
    let fingerprint = data.fingerprint.clone();
    let warm = warm_restart(&config, &fingerprint, opts)?;
    if let Some(w) = warm {
        start = w.step;
    }
    let mut other_data = None;
    if let Some((state, _, _)) = &existing {
        other_data = resume::check_data(state, &fingerprint, opts)?;
        if start >= end {
            return Ok(resume::already_complete(state, &model_config));
        }
    }
    let mut run = setup::start(&config, &model_config, existing, warm, start, opts)?;
    run.cooldown = cooldown;

    let devices: Vec<Device> = std::iter::once(run.device.clone())
        .chain(opts.replicas.iter().map(|d| d.clone().autodiff()))
        .collect();
    if devices.len() > config.batch_size {
        return Err(Error::invalid(
            "--devices",
            format!(
                "{} devices need a batch_size of at least {}, got {}",
                devices.len(),
                devices.len(),
                config.batch_size
            ),
        ));
    }
    let bar = progress_bar(opts.progress, end, start);
    let mut step = start;
    let stop = opts.stop_after.map_or(end, |n| (start + n).min(end));
    let mut batches = Prefetch::new(&config, &data, step, stop, Prefetch::default_depth());
    let (mut saved_at, mut last_save) = (step, Instant::now());
    let (mut last_step, mut last_validation) = (Duration::ZERO, Duration::ZERO);
    // A session's first step and first validation also compile a GPU's kernels (minutes on
    // wgpu): what they took says nothing of the next one, which is expected to take as long
    // as the last step after them.
    let (mut steps_here, mut validations_here) = (0usize, 0usize);
    let mut stopped = None;
    while step < stop {
        let validates = (step + 1) % config.val_every == 0 || step + 1 == end;
        let expected = |last: Duration, done: usize| if done > 1 { last } else { Duration::ZERO };
        let next = expected(last_step, steps_here)
            + if validates {
                expected(last_validation, validations_here)
            } else {
                Duration::ZERO
            };
        if let Some(reason) = budget.should_stop(next) {
            stopped = Some(reason);
            break;
        }
        let t0 = Instant::now();
        let lr = one_cycle(step, config.steps, config.lr, config.pct_start)
            * restart_factor(step, run.restart, config.restart_warmup)
            * cooldown::factor(step, run.cooldown);
        let examples = batches.take(step)?;
        let (model, stats) = match step::take_parallel(
            run.model,
            &mut run.optim,
            examples,
            &devices,
            &config,
            lr,
            step,
            opts,
        ) {
            Ok(taken) => taken,
            Err(e) => {
                bar.abandon();
                return Err(e);
            }
        };
        run.model = model;
        step += 1;
        run.last_loss = Some(stats.loss as f64);
        last_step = t0.elapsed();
        steps_here += 1;
        let ms = last_step.as_secs_f64() * 1e3;
        run.seconds += ms / 1e3;

        let mut row = LogRow {
            step,
            lr,
            loss: stats.loss as f64,
            epe: stats.epe as f64,
            grad_norm: stats.grad_norm,
            ms_per_step: ms,
            val_epe: None,
            val_px1: None,
        };
        if validates {
            let t_val = Instant::now();
            let stamp = save::stamp(&config, step, &fingerprint, run.cooldown);
            let scores = validate::validate(
                &run.model,
                &model_config,
                &data,
                &config,
                opts,
                &mut run.best_val,
                &stamp,
            )?;
            row.val_epe = Some(scores.epe);
            row.val_px1 = Some(scores.px1);
            last_validation = t_val.elapsed();
            validations_here += 1;
        }
        run.log.append(&row)?;
        bar.set_message(format!(
            "loss {:.3} epe {:.2}{}",
            stats.loss,
            stats.epe,
            run.best_val
                .map(|v| format!(" val {v:.2}"))
                .unwrap_or_default()
        ));
        bar.set_position(step as u64);
        if step % config.checkpoint_every == 0
            || step == end
            || step == stop
            || last_save.elapsed() >= opts.checkpoint_interval
        {
            save::save(&run, &config, &model_config, step, &fingerprint, opts)?;
            (saved_at, last_save) = (step, Instant::now());
        }
    }
    if saved_at != step || !checkpoint::dir(&opts.out).join("state.json").is_file() {
        save::save(&run, &config, &model_config, step, &fingerprint, opts)?;
    }
    bar.finish_and_clear();
    Ok(TrainSummary {
        steps: step,
        last_loss: run.last_loss,
        best_val_epe: run.best_val,
        train_seconds: run.seconds,
        parameters: run.parameters,
        already_complete: false,
        pairs_seen: (step * config.batch_size) as u64,
        stopped,
        other_data,
    })
}

/// The warm restart `opts.continue_from` asks for: the step its stamp stands at (the weights
/// must come from this config and these data).
fn warm_restart(
    config: &TrainConfig,
    fingerprint: &DataFingerprint,
    opts: &TrainOptions,
) -> Result<Option<WarmRestart>> {
    let Some(path) = &opts.continue_from else {
        return Ok(None);
    };
    if opts.resume || opts.init.is_some() {
        return Err(Error::invalid(
            "--continue-from",
            "cannot be combined with --resume or --init (each names where the run starts)",
        ));
    }
    let bytes = crate::io::read_bytes(path)?;
    let stamp = TrainingStamp::read(&bytes, path)?.ok_or_else(|| {
        Error::invalid(
            "--continue-from",
            format!(
                "{} carries no training stamp (it was not written by this version of pins \
                 train): use --init to fine-tune from it",
                path.display()
            ),
        )
    })?;
    Ok(Some(WarmRestart {
        step: stamp.restart_step(config, fingerprint, path)?,
    }))
}

/// The progress bar of a run of `steps` steps from `start` (hidden unless `shown`).
fn progress_bar(shown: bool, steps: usize, start: usize) -> ProgressBar {
    let bar = if shown {
        ProgressBar::new(steps as u64)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} {msg} [{elapsed} < {eta}]")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar.set_position(start as u64);
    bar
}

/// The run folder's exported weights: `best.safetensors` if validation ran, else `last`.
pub fn run_weights(run: &Path) -> Result<PathBuf> {
    for name in ["best.safetensors", "last.safetensors"] {
        let p = run.join(name);
        if p.is_file() {
            return Ok(p);
        }
    }
    Err(Error::invalid(
        "--run",
        format!(
            "{} holds no trained weights (best.safetensors or last.safetensors)",
            run.display()
        ),
    ))
}
