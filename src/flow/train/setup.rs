//! Setting a run up (Note S11): the crop checked against the images, the network (initial
//! weights a function of the seed, parameter ids from their paths, or `--init` weights), the
//! AdamW optimiser, the state restored from a checkpoint, and the run folder with its
//! `config.json` and log.

use burn::optim::{AdamWConfig, ModuleOptimizer};
use burn::prelude::*;
use burn::store::ModuleRecord;
use burn::tensor::Bytes;

use super::checkpoint::Loaded;
use super::config::TrainConfig;
use super::cooldown::Cooldown;
use super::log::TrainLog;
use super::options::TrainOptions;
use crate::error::{Error, Result};
use crate::flow::model::{Mms, MmsConfig};
use crate::flow::weights;
use crate::rng;

/// A run in progress: the network and optimiser with what has been recorded so far.
pub struct Run {
    /// The autodiff device the run trains on.
    pub device: Device,
    pub model: Mms,
    pub optim: ModuleOptimizer,
    /// The first step of this session.
    pub start: usize,
    pub best_val: Option<f64>,
    /// Training time over all sessions.
    pub seconds: f64,
    pub last_loss: Option<f64>,
    pub log: TrainLog,
    pub parameters: usize,
    /// The step of a warm restart (`--continue-from`), whose learning-rate warm-up the
    /// schedule applies (kept by checkpoints, so a resumed run repeats it).
    pub restart: Option<usize>,
    /// The cool-down the run ends with ([`super::cooldown`]), kept by its checkpoints.
    pub cooldown: Option<Cooldown>,
}

/// Where a new run's schedule starts when it continues from a weights file alone: the
/// stamp's step. (Its training time is not in the file: the ledger keeps the hours.)
#[derive(Clone, Copy, Debug)]
pub struct WarmRestart {
    pub step: usize,
}

/// The network and optimiser of a new run (warm-restarted when `warm` is given), or of
/// `existing` restored, starting at `start`; the run folder written.
pub fn start(
    config: &TrainConfig,
    model_config: &MmsConfig,
    existing: Option<Loaded>,
    warm: Option<WarmRestart>,
    start: usize,
    opts: &TrainOptions,
) -> Result<Run> {
    let device = opts.device.clone().autodiff();
    let mut model = network(config, model_config, &device, opts)?;
    let mut optim = AdamWConfig::new()
        .with_weight_decay(config.weight_decay as f32)
        .with_epsilon(config.epsilon as f32)
        .init();
    let (mut best_val, mut seconds, mut last_loss) = (None, 0.0, None);
    let mut restart = warm.map(|w| w.step);
    if let Some((state, model_bytes, optim_bytes)) = existing {
        let record = ModuleRecord::from_bytes(Bytes::from_bytes_vec(model_bytes))
            .map_err(|e| record_error("checkpoint model", e))?;
        model = model
            .try_load_record(record)
            .map_err(|e| record_error("checkpoint model", e))?;
        optim = optim
            .from_bytes(Bytes::from_bytes_vec(optim_bytes))
            .map_err(|e| record_error("checkpoint optimiser", e))?;
        // A branch (`--branch-from`) validates on its own: its best.safetensors is one of its
        // steps, not a score of the run it left.
        best_val = state.best_val_epe.filter(|_| opts.branch_from.is_none());
        seconds = state.train_seconds;
        last_loss = state.last_loss;
        restart = state.restart_step;
    }
    std::fs::create_dir_all(&opts.out).map_err(|e| Error::io(&opts.out, e))?;
    let run_json = serde_json::json!({"train": config, "model": model_config, "data": opts.data});
    crate::io::write_bytes_atomic(
        &opts.out.join("config.json"),
        serde_json::to_string_pretty(&run_json)
            .unwrap_or_default()
            .as_bytes(),
    )?;
    let log_path = opts.out.join("log.csv");
    if let Some(trunk) = &opts.branch_from {
        // A branch's curves begin with its run's.
        let from = trunk.join("log.csv");
        if from.is_file() && !log_path.exists() {
            std::fs::copy(&from, &log_path).map_err(|e| Error::io(&from, e))?;
        }
    }
    let log = TrainLog::open(&log_path, start)?;
    let parameters = weights::parameter_count(&model);
    Ok(Run {
        device,
        model,
        optim,
        start,
        best_val,
        seconds,
        last_loss,
        log,
        parameters,
        restart,
        cooldown: None,
    })
}

/// An error of a checkpoint's record.
pub fn record_error(what: &str, e: impl std::fmt::Display) -> Error {
    Error::invalid(what, e.to_string())
}

/// The initial network: seeded, or the `--init` / `--continue-from` weights (not with
/// `--resume`).
fn network(
    config: &TrainConfig,
    model_config: &MmsConfig,
    device: &Device,
    opts: &TrainOptions,
) -> Result<Mms> {
    // The initial weights are a function of the seed too, so two runs of one config agree.
    device.seed(rng::derive(config.seed, &[rng::purpose::TRAIN, u64::MAX]));
    // Ids from parameter paths, so that checkpoints of equal runs are equal files.
    let mut model = super::param_ids::ids_from_paths(Mms::new(model_config, device));
    let (flag, init) = match (&opts.init, &opts.continue_from) {
        (Some(p), None) => ("--init", p),
        (None, Some(p)) => ("--continue-from", p),
        (None, None) => return Ok(model),
        (Some(_), Some(_)) => {
            return Err(Error::invalid(
                "--init",
                "cannot be combined with --continue-from (both name the starting weights)",
            ));
        }
    };
    if opts.resume {
        return Err(Error::invalid(
            flag,
            "cannot be combined with --resume (the checkpoint already holds the weights)",
        ));
    }
    let bytes = crate::io::read_bytes(init)?;
    let stored = weights::read_config(&bytes, init)?;
    if stored != *model_config {
        return Err(Error::invalid(
            flag,
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
    Ok(model)
}
