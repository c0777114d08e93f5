//! What a training session is given (folders, devices, how it may end) and what it returns.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use burn::prelude::*;
use serde::Serialize;

use super::budget::StopReason;

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
    /// Further devices for data-parallel training (`--devices a,b,…`: `device` is the first);
    /// each step's batch is spread over all of them and the result does not depend on how
    /// many there are (see [`super::step::take_parallel`]).
    pub replicas: Vec<Device>,
    /// Start a new run from these weights (fine-tuning) instead of a random initialisation.
    pub init: Option<PathBuf>,
    /// Start a new run where these weights' run stood (their training stamp: same config,
    /// same schedule and data order), with a learning-rate warm-up: a warm restart when the
    /// checkpoint is gone.
    pub continue_from: Option<PathBuf>,
    /// End the session (with a checkpoint) before the step that would pass this much time.
    pub time_budget: Option<Duration>,
    /// Set by a signal handler: end the session (with a checkpoint) before the next step.
    pub stop: Option<Arc<AtomicBool>>,
    /// Write a checkpoint when this much time has passed since the last one.
    pub checkpoint_interval: Duration,
    /// Keep the weights of every checkpoint in this folder as `step-NNNNNNN.safetensors`
    /// (stamped), for weight averaging ([`crate::flow::average`]).
    pub snapshots: Option<PathBuf>,
    /// Start `out` as a branch of the run in this folder: its checkpoint (weights, optimiser
    /// state, step, config, data order) copied, the run itself untouched.
    pub branch_from: Option<PathBuf>,
    /// Take the learning rate down to zero over this many steps from where the run (or the
    /// branch) stands, and end there ([`super::cooldown`]).
    pub cooldown: Option<usize>,
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
    /// Training pairs seen over the whole run (steps × batch).
    pub pairs_seen: u64,
    /// Why the session ended before the run's last step and `--stop-after`, if it did.
    pub stopped: Option<StopReason>,
    /// A new cool-down branch that anneals on data other than its run's: which (a line).
    pub other_data: Option<String>,
}
