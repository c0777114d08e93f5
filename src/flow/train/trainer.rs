//! `pins train`: the MMS network on a generated dataset with the sequence loss of Eq. S16,
//! AdamW, the one-cycle schedule and global gradient clipping; held-out validation on a
//! schedule; atomic checkpoints from which `--resume` continues exactly (same step, optimiser
//! state, schedule and data order); a CSV log and a PNG plot of the curves.

use std::path::{Path, PathBuf};
use std::time::Instant;

use burn::optim::{AdamWConfig, GradientsParams};
use burn::prelude::*;
use burn::store::ModuleRecord;
use burn::tensor::Bytes;
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;

use super::checkpoint::{self, CheckpointState};
use super::clip::clip_global_norm;
use super::config::TrainConfig;
use super::log::{LogRow, TrainLog};
use super::schedule::one_cycle;
use crate::error::{Error, Result};
use crate::flow::data::{Batch, FlowDataset, make_example};
use crate::flow::eval::evaluate_dataset;
use crate::flow::loss::{mean_epe, sequence_loss};
use crate::flow::model::Mms;
use crate::flow::weights;
use crate::rng;

/// Where and how to run.
#[derive(Clone, Debug)]
pub struct TrainOptions {
    pub data: PathBuf,
    pub out: PathBuf,
    pub resume: bool,
    /// Overrides the config's step count (not allowed to change it on resume).
    pub steps: Option<usize>,
    /// Stop (with a checkpoint) after this many steps in this session, keeping the schedule
    /// of the whole run: training in chunks, continued with `resume`.
    pub stop_after: Option<usize>,
    pub progress: bool,
    /// Where to train (`Device::flex()` by default, see [`crate::flow::device::select`]).
    pub device: Device,
    /// Start a new run from these weights (fine-tuning) instead of a random initialisation.
    pub init: Option<PathBuf>,
}

/// What a run ended with.
#[derive(Clone, Debug, Serialize)]
pub struct TrainSummary {
    pub steps: usize,
    /// Loss of the last step taken (`None` when no step was ever taken).
    pub last_loss: Option<f64>,
    pub best_val_epe: Option<f64>,
    pub train_seconds: f64,
    pub parameters: usize,
    /// The run had already taken all its steps: nothing was trained in this call.
    pub already_complete: bool,
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

fn record_error(what: &str, e: impl std::fmt::Display) -> Error {
    Error::invalid(what, e.to_string())
}

/// Trains (or resumes) a run. `config` is the run's config: required to be equal to the stored
/// one when resuming (`None` then means "the stored one"), the defaults when `None` on a new run.
pub fn train(config: Option<TrainConfig>, opts: &TrainOptions) -> Result<TrainSummary> {
    let existing = checkpoint::read(&opts.out)?;
    let (mut config, start) = match (&existing, opts.resume) {
        (Some((state, _, _)), true) => {
            if let Some(given) = &config {
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
        (None, false) => (config.unwrap_or_default(), 0),
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
    let model_config = config.model_config()?;
    let dataset = FlowDataset::open(&opts.data)?;
    let fingerprint = dataset.fingerprint()?;
    if let Some((state, _, _)) = &existing
        && let Some(stored) = &state.data_fingerprint
        && *stored != fingerprint
    {
        return Err(Error::invalid(
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
        ));
    }
    if let Some((state, _, _)) = &existing
        && start >= config.steps
    {
        return Ok(TrainSummary {
            steps: start,
            last_loss: state.last_loss,
            best_val_epe: state.best_val_epe,
            train_seconds: state.train_seconds,
            parameters: weights::parameter_count(&Mms::new(&model_config, &Device::flex())),
            already_complete: true,
        });
    }
    dataset.check_has_known_flow()?;
    let (train_set, val_set) = dataset.split(config.val_fraction);
    // Fail early on images smaller than the crop.
    let (a, _, _) = train_set.load(0)?;
    if a.height() < config.crop[0] || a.width() < config.crop[1] {
        return Err(Error::invalid(
            "train.crop",
            format!(
                "{:?} is larger than the {}x{} images of {}",
                config.crop,
                a.height(),
                a.width(),
                opts.data.display()
            ),
        ));
    }

    let device = opts.device.clone().autodiff();
    // The initial weights are a function of the seed too, so two runs of one config agree.
    device.seed(rng::derive(config.seed, &[rng::purpose::TRAIN, u64::MAX]));
    // Ids from parameter paths, so that checkpoints of equal runs are equal files.
    let mut model = super::param_ids::ids_from_paths(Mms::new(&model_config, &device));
    if let Some(init) = &opts.init {
        if opts.resume {
            return Err(Error::invalid(
                "--init",
                "cannot be combined with --resume (the checkpoint already holds the weights)",
            ));
        }
        let bytes = crate::io::read_bytes(init)?;
        let stored = weights::read_config(&bytes, init)?;
        if stored != model_config {
            return Err(Error::invalid(
                "--init",
                format!(
                    "{} holds a {} network, but the run trains {}",
                    init.display(),
                    stored.name,
                    model_config.name
                ),
            ));
        }
        let mut store = burn::store::SafetensorsStore::from_bytes(Some(bytes))
            .validate(true)
            .allow_partial(false);
        burn::store::ModuleSnapshot::load_from(&mut model, &mut store)
            .map_err(|e| Error::format(init, format!("cannot load the weights: {e}")))?;
    }
    let mut optim = AdamWConfig::new()
        .with_weight_decay(config.weight_decay as f32)
        .with_epsilon(config.epsilon as f32)
        .init();
    let mut best_val = None;
    let mut seconds = 0.0;
    let mut existing_last_loss = None;
    if let Some((state, model_bytes, optim_bytes)) = existing {
        let record = ModuleRecord::from_bytes(Bytes::from_bytes_vec(model_bytes))
            .map_err(|e| record_error("checkpoint model", e))?;
        model = model
            .try_load_record(record)
            .map_err(|e| record_error("checkpoint model", e))?;
        optim = optim
            .from_bytes(Bytes::from_bytes_vec(optim_bytes))
            .map_err(|e| record_error("checkpoint optimiser", e))?;
        best_val = state.best_val_epe;
        seconds = state.train_seconds;
        existing_last_loss = state.last_loss;
    }
    std::fs::create_dir_all(&opts.out).map_err(|e| Error::io(&opts.out, e))?;
    let run_json = serde_json::json!({"train": config, "model": model_config, "data": opts.data});
    crate::io::write_bytes_atomic(
        &opts.out.join("config.json"),
        serde_json::to_string_pretty(&run_json)
            .unwrap_or_default()
            .as_bytes(),
    )?;
    let mut log = TrainLog::open(&opts.out.join("log.csv"), start)?;
    let parameters = weights::parameter_count(&model);

    let bar = if opts.progress {
        ProgressBar::new(config.steps as u64)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} {msg} [{elapsed} < {eta}]")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar.set_position(start as u64);
    let mut last_loss = existing_last_loss;
    let mut step = start;
    let stop = opts
        .stop_after
        .map_or(config.steps, |n| (start + n).min(config.steps));
    while step < stop {
        let t0 = Instant::now();
        let lr = one_cycle(step, config.steps, config.lr, config.pct_start);
        // The batch of step s depends on (seed, s) alone: resuming replays the same data order.
        let mut r = rng::stream(config.seed, &[rng::purpose::TRAIN, step as u64]);
        let mut examples = Vec::with_capacity(config.batch_size);
        for _ in 0..config.batch_size {
            let i = rand::RngExt::random_range(&mut r, 0..train_set.pairs.len());
            let (a, b, f) = train_set.load(i)?;
            examples.push(make_example(
                &a,
                &b,
                &f,
                (config.crop[0], config.crop[1]),
                &config.augment,
                &mut r,
            )?);
        }
        let batch = Batch::stack(examples, config.crop[0], config.crop[1], &device);
        let preds = model.forward(batch.img1, batch.img2, config.iters, true);
        let loss = sequence_loss(&preds, batch.flow.clone(), batch.valid.clone(), config.rho);
        let loss_value: f32 = loss.clone().into_scalar();
        if !loss_value.is_finite() {
            bar.abandon();
            return Err(Error::invalid(
                "training",
                format!(
                    "loss became {loss_value} at step {step}; stopped. The last good checkpoint (step {}) is kept in {}",
                    checkpoint::read(&opts.out)
                        .ok()
                        .flatten()
                        .map(|c| c.0.step)
                        .unwrap_or(0),
                    checkpoint::dir(&opts.out).display()
                ),
            ));
        }
        let epe = preds
            .last()
            .map(|p| mean_epe(p.clone(), batch.flow, batch.valid))
            .unwrap_or(f32::NAN);
        let mut grads = GradientsParams::from_grads(loss.backward(), &model);
        let grad_norm = clip_global_norm(&model, &mut grads, config.clip);
        if !grad_norm.is_finite() {
            bar.abandon();
            return Err(Error::invalid(
                "training",
                format!(
                    "gradient norm became {grad_norm} at step {step}; stopped, last checkpoint kept"
                ),
            ));
        }
        model = optim.step(lr, model, grads);
        step += 1;
        last_loss = Some(loss_value as f64);
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        seconds += ms / 1e3;

        let mut row = LogRow {
            step,
            lr,
            loss: loss_value as f64,
            epe: epe as f64,
            grad_norm,
            ms_per_step: ms,
            val_epe: None,
            val_px1: None,
        };
        if step % config.val_every == 0 || step == config.steps {
            let valid_model = model.valid();
            let scores = evaluate_dataset(
                &valid_model,
                &model_config,
                &val_set,
                config.val_iters,
                config.val_max_pairs,
                &opts.device,
            )?;
            row.val_epe = Some(scores.epe);
            row.val_px1 = Some(scores.px1);
            if best_val.is_none_or(|b| scores.epe < b) {
                best_val = Some(scores.epe);
                weights::save(
                    &opts.out.join("best.safetensors"),
                    &valid_model,
                    &model_config,
                )?;
            }
        }
        log.append(&row)?;
        bar.set_message(format!(
            "loss {:.3} epe {:.2}{}",
            loss_value,
            epe,
            best_val.map(|v| format!(" val {v:.2}")).unwrap_or_default()
        ));
        bar.set_position(step as u64);
        if step % config.checkpoint_every == 0 || step == config.steps || step == stop {
            let model_bytes = model
                .clone()
                .into_record()
                .into_bytes()
                .map_err(|e| record_error("checkpoint model", e))?;
            let optim_bytes = optim
                .into_bytes()
                .map_err(|e| record_error("checkpoint optimiser", e))?;
            let state = CheckpointState {
                step,
                model_file: format!("model-{step:07}.bpk"),
                optimizer_file: format!("optim-{step:07}.bin"),
                config: config.clone(),
                config_sha256: Some(checkpoint::config_sha256(&config)?),
                data: opts.data.clone(),
                data_fingerprint: Some(fingerprint.clone()),
                best_val_epe: best_val,
                last_loss,
                train_seconds: seconds,
            };
            checkpoint::write(&opts.out, &state, &model_bytes, &optim_bytes)?;
            weights::save(
                &opts.out.join("last.safetensors"),
                &model.valid(),
                &model_config,
            )?;
            log.plot(&opts.out.join("curves.png"))?;
        }
    }
    bar.finish_and_clear();
    Ok(TrainSummary {
        steps: step,
        last_loss,
        best_val_epe: best_val,
        train_seconds: seconds,
        parameters,
        already_complete: false,
    })
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
