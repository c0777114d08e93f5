//! `pins train`, `pins export` and `pins average`: training the MMS network (Note S11), its
//! weights out of a run, and the mean of several weights files.

use std::io::IsTerminal;
use std::path::PathBuf;

use anyhow::{Context, Result};

#[derive(clap::Args)]
pub(crate) struct TrainArgs {
    /// Training config (JSON); the shipped small-model defaults when absent.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Dataset folder (from `pins generate`, or FlyingChairs/Sintel/Middlebury/KITTI layout), or
    /// a stream file (`.json`: generator configs with weights) whose pairs are made on the fly
    /// as the steps need them, each one new (see docs/training.md).
    #[arg(long)]
    data: PathBuf,
    /// Run folder: checkpoints, log.csv, curves.png, best/last.safetensors.
    #[arg(long)]
    out: PathBuf,
    /// Total steps (overrides the config).
    #[arg(long)]
    steps: Option<usize>,
    /// Continue the run in --out from its last checkpoint.
    #[arg(long)]
    resume: bool,
    /// Device: cpu, or a GPU backend of this build (wgpu[:N], cuda[:N]).
    #[arg(long, default_value = "cpu")]
    device: String,
    /// Data-parallel training over several devices, e.g. `cpu,cpu`, `wgpu:0,wgpu:1` or `cuda:0,cuda:1`: each
    /// step's batch is split among them and the gradients summed on the first; the result does
    /// not depend on the number of devices. Replaces --device.
    #[arg(long, value_delimiter = ',', conflicts_with = "device")]
    devices: Option<Vec<String>>,
    /// Start from these weights (fine-tuning) instead of a random initialisation.
    #[arg(long, conflicts_with_all = ["resume", "continue_from"])]
    init: Option<PathBuf>,
    /// Go on from a weights file of this run (last/best.safetensors, or an export of them) when
    /// its checkpoint is gone: the run starts at the step the file's training stamp records, on
    /// the same schedule and data order, with a short learning-rate warm-up (the config's
    /// restart_warmup) while the optimiser's moments are rebuilt.
    #[arg(long, conflicts_with = "resume")]
    continue_from: Option<PathBuf>,
    /// End this session before the step that would pass this much wall-clock time, with a
    /// checkpoint (e.g. 2h30m, 90m, 45s); continue with --resume. SIGTERM and Ctrl-C end it the
    /// same way at the next step (a second Ctrl-C stops at once).
    #[arg(long, value_parser = parse_budget)]
    time_budget: Option<std::time::Duration>,
    /// Stop after this many steps in this session (a checkpoint is written); continue later
    /// with --resume. The learning-rate schedule still spans the whole run.
    #[arg(long)]
    stop_after: Option<usize>,
    /// Also keep the weights of every checkpoint in this folder (step-NNNNNNN.safetensors,
    /// stamped): snapshots for `pins average`.
    #[arg(long)]
    snapshots: Option<PathBuf>,
    /// Start --out as a branch of the run in this folder: its last checkpoint (weights,
    /// optimiser state, step, config, data order) is the branch's first; the run is untouched.
    #[arg(long, conflicts_with_all = ["resume", "init", "continue_from"])]
    branch_from: Option<PathBuf>,
    /// Cool down: take the learning rate to zero over this many steps (1 − √t of the
    /// schedule's rate) from where the run stands, and end there. With --branch-from (the run
    /// goes on elsewhere: a warmup–stable–decay campaign; the branch may anneal on other
    /// --data, which its checkpoint then keeps) or --resume (this run ends).
    #[arg(long, conflicts_with_all = ["init", "continue_from"])]
    cooldown: Option<usize>,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

#[derive(clap::Args)]
pub(crate) struct ExportArgs {
    /// Training run folder.
    #[arg(long)]
    run: PathBuf,
    /// Output weights file (.safetensors).
    #[arg(long)]
    out: PathBuf,
}

#[derive(clap::Args)]
pub(crate) struct AverageArgs {
    /// Weights files of one network (two or more), e.g. snapshots of one training run.
    #[arg(required = true, num_args = 2..)]
    weights: Vec<PathBuf>,
    /// Output weights file (.safetensors); written only when every input fits.
    #[arg(long)]
    out: PathBuf,
}

fn parse_budget(text: &str) -> std::result::Result<std::time::Duration, String> {
    pins::flow::train::budget::parse_duration(text).map_err(|e| e.to_string())
}

/// A flag that SIGTERM and Ctrl-C set, so that training ends at the next step with a
/// checkpoint; a second signal while it is set ends the process at once.
fn stop_flag() -> Result<std::sync::Arc<std::sync::atomic::AtomicBool>> {
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register_conditional_shutdown(sig, 1, stop.clone())
            .context("installing the stop handler")?;
        signal_hook::flag::register(sig, stop.clone()).context("installing the stop handler")?;
    }
    Ok(stop)
}

pub(crate) fn train(a: TrainArgs) -> Result<()> {
    use pins::flow::train::{TrainConfig, TrainOptions};
    let config = match &a.config {
        Some(p) => Some(TrainConfig::from_file(p)?),
        None => None,
    };
    let model = config.clone().unwrap_or_default().model_config()?;
    let params = pins::flow::weights::parameter_count(&pins::flow::model::Mms::new(
        &model,
        &burn::prelude::Device::flex(),
    ));
    println!(
        "training {} ({params} parameters) on {}",
        model.name,
        a.data.display()
    );
    let names = a.devices.clone().unwrap_or_else(|| vec![a.device.clone()]);
    let mut devices = names
        .iter()
        .map(|n| pins::flow::device::select(n.trim()))
        .collect::<pins::error::Result<Vec<_>>>()?;
    if devices.is_empty() {
        anyhow::bail!("--devices: name at least one device");
    }
    let device = devices.remove(0);
    let replicas = devices;
    let opts = TrainOptions {
        data: a.data,
        out: a.out.clone(),
        resume: a.resume,
        steps: a.steps,
        stop_after: a.stop_after,
        init: a.init,
        continue_from: a.continue_from,
        time_budget: a.time_budget,
        stop: Some(stop_flag()?),
        checkpoint_interval: pins::flow::train::budget::CHECKPOINT_INTERVAL,
        snapshots: a.snapshots,
        branch_from: a.branch_from,
        cooldown: a.cooldown,
        device,
        replicas,
        progress: !a.quiet && std::io::stderr().is_terminal(),
    };
    let s = pins::flow::train::train(config, &opts)?;
    if let Some(note) = &s.other_data {
        println!("{}: {note}", a.out.display());
    }
    if s.already_complete {
        println!(
            "{}: the run is already complete ({} of {} steps); nothing to do",
            a.out.display(),
            s.steps,
            s.steps
        );
    }
    if let Some(reason) = s.stopped {
        println!(
            "{}: stopped by {reason} after step {}, checkpoint written; continue with --resume",
            a.out.display(),
            s.steps
        );
    }
    println!(
        "{}: {} steps ({} pairs seen), last loss {}, best validation EPE {}, {:.0} s of training",
        a.out.display(),
        s.steps,
        s.pairs_seen,
        s.last_loss
            .map(|v| format!("{v:.4}"))
            .unwrap_or_else(|| "–".into()),
        s.best_val_epe
            .map(|v| format!("{v:.3}"))
            .unwrap_or_else(|| "–".into()),
        s.train_seconds
    );
    Ok(())
}

pub(crate) fn export(a: ExportArgs) -> Result<()> {
    let src = pins::flow::train::trainer::run_weights(&a.run)?;
    let device = burn::prelude::Device::flex();
    let bytes = pins::io::read_bytes(&src)?;
    let (model, config) = pins::flow::weights::from_bytes(&bytes, &src, &device)?;
    // The training stamp goes with the weights, so that a run can continue from the export.
    let stamp = pins::flow::train::stamp::TrainingStamp::read(&bytes, &src)?;
    let extra = stamp.map(|s| s.entry()).transpose()?;
    pins::flow::weights::save_with(&a.out, &model, &config, extra.as_slice())?;
    println!(
        "{} → {} ({}, {} parameters)",
        src.display(),
        a.out.display(),
        config.name,
        pins::flow::weights::parameter_count(&model)
    );
    Ok(())
}

pub(crate) fn average(a: AverageArgs) -> Result<()> {
    let avg = pins::flow::average::average(&a.weights)?;
    pins::io::write_bytes_atomic(&a.out, &avg.bytes)?;
    let steps: Vec<String> = avg
        .steps
        .iter()
        .map(|s| s.map_or_else(|| "–".into(), |s| s.to_string()))
        .collect();
    println!(
        "{} files (steps {}) → {} ({}, {} parameters)",
        a.weights.len(),
        steps.join(", "),
        a.out.display(),
        avg.config.name,
        avg.parameters
    );
    Ok(())
}
