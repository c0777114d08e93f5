//! Commands of the MMS flow network: train, export, infer, eval, bench-flow, bench-real,
//! detect-limits.

use std::io::IsTerminal;
use std::path::PathBuf;

use anyhow::{Context, Result, bail};

use pins::io::{self, BitDepth};

#[derive(clap::Args)]
pub(crate) struct BenchFlowArgs {
    /// mms or mms-small.
    #[arg(long, default_value = "mms-small")]
    model: String,
    /// infer (batch 1), train (batch 2, one AdamW step), kernels (every heavy operation of
    /// one pair against the machine's gemm peak, a markdown table; --iters updates; cpu only)
    /// or refine (the variational refinement alone, on a warped texture pair; --model, --iters
    /// and --device unused).
    #[arg(long, default_value = "infer")]
    mode: String,
    #[arg(long, default_value_t = 368)]
    height: usize,
    #[arg(long, default_value_t = 496)]
    width: usize,
    #[arg(long, default_value_t = 12)]
    iters: usize,
    #[arg(long, default_value_t = 3)]
    reps: usize,
    /// Device: cpu, or a GPU backend of this build (wgpu[:N], cuda[:N]).
    #[arg(long, default_value = "cpu")]
    device: String,
    /// --mode refine: the settings, `variational` (the defaults) or a .json file of them.
    #[arg(long, default_value = "variational")]
    refine: String,
    /// --mode refine: also write the pair there (frame1.png, frame2.png, start.flo,
    /// truth.flo), for timing another refinement on the same frames.
    #[arg(long)]
    pair_out: Option<PathBuf>,
}

#[derive(clap::Args)]
pub(crate) struct BenchRealArgs {
    /// Benchmark config (JSON): sets, cameras, weights, iteration counts
    /// (experiments/bench_real.json).
    #[arg(long)]
    config: PathBuf,
    /// Output folder: report.json, report.md, epe_vs_ms_CAMERA.png, and data/ (the generated
    /// pairs, kept and reused by the next run of the same config).
    #[arg(long)]
    out: PathBuf,
    /// Weights file, or built-in weights (default = mms-small-real, mms-small); overrides the config's.
    #[arg(long)]
    weights: Option<String>,
    /// Iteration counts; override the config's.
    #[arg(long, value_delimiter = ',')]
    iters: Option<Vec<usize>>,
    /// Do not run the OpenCV peers.
    #[arg(long)]
    no_peers: bool,
    /// Also score MMS followed by the variational refinement (`variational`) or only the
    /// network (`none`).
    #[arg(long, default_value = "variational")]
    refine: String,
    /// Where the network starts: coarse (from its own flow at half resolution, upsampled:
    /// large motions are found) or zero (RAFT's start).
    #[arg(long, default_value = "coarse")]
    start: String,
    /// Python interpreter for the OpenCV peers (scripts/flow_baselines.py, built in).
    #[arg(long, default_value = "python3")]
    python: String,
    /// Device: cpu, or a GPU backend of this build (wgpu[:N], cuda[:N]).
    #[arg(long, default_value = "cpu")]
    device: String,
}

#[derive(clap::Args)]
pub(crate) struct BenchLiveArgs {
    /// Benchmark config (JSON): clips, tracking settings, operating points, DIS presets
    /// (experiments/bench_live.json).
    #[arg(long)]
    config: PathBuf,
    /// Output folder: report.json, report.md and two charts per clip.
    #[arg(long)]
    out: PathBuf,
    /// Do not run DIS.
    #[arg(long)]
    no_peers: bool,
    /// Python interpreter for DIS (scripts/dis_flows.py, built in).
    #[arg(long, default_value = "python3")]
    python: String,
    /// Device for MMS: cpu, or a GPU backend of this build (wgpu[:N], cuda[:N]).
    #[arg(long, default_value = "cpu")]
    device: String,
}

#[derive(clap::Args)]
pub(crate) struct DetectLimitsArgs {
    /// Experiment config (JSON): cases, camera, iteration counts, detection rule; Note S12's
    /// six cases through the default camera when absent (experiments/s12_limits.json).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Output folder: report.json, report.md and fig_s10.png.
    #[arg(long)]
    out: PathBuf,
    /// Weights file, or built-in weights: default (= mms-small-real, stage 5), mms-small (stage 3).
    #[arg(long, default_value = "default")]
    weights: String,
    /// Iteration counts; override the config's.
    #[arg(long, value_delimiter = ',')]
    iters: Option<Vec<usize>>,
    /// What follows MMS: variational (coarse-to-fine variational refinement) or none.
    #[arg(long, default_value = "variational")]
    refine: String,
    /// Where the network starts: coarse (from its own flow at half resolution) or zero.
    #[arg(long, default_value = "coarse")]
    start: String,
    /// Device: cpu, or a GPU backend of this build (wgpu[:N], cuda[:N]).
    #[arg(long, default_value = "cpu")]
    device: String,
}

#[derive(clap::Args)]
pub(crate) struct TrainArgs {
    /// Training config (JSON); the shipped small-model defaults when absent.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Dataset folder (from `pins generate`, or FlyingChairs/Sintel/Middlebury/KITTI layout).
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
    /// goes on elsewhere: a warmup–stable–decay campaign) or --resume (this run ends).
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

#[derive(clap::Args)]
pub(crate) struct InferArgs {
    /// Weights file, or built-in weights: default (= mms-small-real, stage 5), mms-small (stage 3).
    #[arg(long, default_value = "default")]
    weights: String,
    /// First image (or, with --frames, omit both images).
    #[arg(long)]
    img1: Option<PathBuf>,
    /// Second image.
    #[arg(long)]
    img2: Option<PathBuf>,
    /// A folder of frames: flow between each consecutive pair (sorted by name).
    #[arg(long)]
    frames: Option<PathBuf>,
    /// Output .flo file (or folder with --frames).
    #[arg(long)]
    out: PathBuf,
    /// Also write the Middlebury colour-wheel visualisation (PNG; a folder with --frames).
    #[arg(long)]
    viz: Option<PathBuf>,
    /// Refinement iterations: a count, or auto (at most the weights' own, stopping once the
    /// flow settles); the weights' own when absent.
    #[arg(long)]
    iters: Option<pins::flow::iters::Iters>,
    /// What follows the network: variational (coarse-to-fine variational refinement) or none.
    #[arg(long, default_value = "variational")]
    refine: String,
    /// Where the network starts: coarse (from its own flow at half resolution, upsampled:
    /// large motions are found) or zero (RAFT's start).
    #[arg(long, default_value = "coarse")]
    start: String,
    /// With --frames: start each pair from the previous pair's flow, carried forward (RAFT's
    /// warm start on video), instead of --start.
    #[arg(long)]
    warm_start: bool,
    /// With --frames: encode every frame twice, as the second and the first of its pairs (the
    /// same flow, slower).
    #[arg(long)]
    no_reuse: bool,
    /// Device: cpu, or a GPU backend of this build (wgpu[:N], cuda[:N]).
    #[arg(long, default_value = "cpu")]
    device: String,
    /// Run the network at this multiple of the frames' size, in (0, 4]: below 1 faster, above
    /// 1 (frames interpolated) small movers are seen larger, at the square of the scale in
    /// time. The flow is resampled to the frames' size, in their pixels.
    #[arg(long, default_value_t = 1.0)]
    scale: f64,
}

#[derive(clap::Args)]
pub(crate) struct EvalArgs {
    /// Weights file, or built-in weights: default (= mms-small-real, stage 5), mms-small (stage 3).
    #[arg(long, default_value = "default")]
    weights: String,
    /// Dataset folder with ground-truth flow.
    #[arg(long)]
    data: PathBuf,
    /// Iteration counts to evaluate.
    #[arg(long, value_delimiter = ',', default_value = "4,8,12,16")]
    iters: Vec<usize>,
    /// report.json path (a PNG of EPE against ms per pair is written beside it).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Peer results to draw on the same plot (JSON from scripts/flow_baselines.py).
    #[arg(long)]
    peers: Option<PathBuf>,
    /// Also score the network's flow after the variational refinement (`variational`, rows
    /// marked "+ variational"), or only the network (`none`).
    #[arg(long, default_value = "variational")]
    refine: String,
    /// Where the network starts: coarse (from its own flow at half resolution, upsampled:
    /// large motions are found) or zero (RAFT's start).
    #[arg(long, default_value = "coarse")]
    start: String,
    /// Device: cpu, or a GPU backend of this build (wgpu[:N], cuda[:N]).
    #[arg(long, default_value = "cpu")]
    device: String,
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

pub(crate) fn infer(a: InferArgs) -> Result<()> {
    use pins::flow::{infer::Predictor, sequence::pair_flows_scaled, viz::flow_to_image};
    pins::flow::scale::check_scale(a.scale)
        .map_err(|_| anyhow::anyhow!("--scale must be in (0, 4], got {}", a.scale))?;
    // The frames, and where the flow of each pair (n, n + 1) goes.
    let (frames, outputs): (Vec<PathBuf>, Vec<(PathBuf, Option<PathBuf>)>) =
        match (&a.frames, &a.img1, &a.img2) {
            (Some(dir), None, None) => {
                let frames = io::frame_files(dir)?;
                let outputs = frames
                    .iter()
                    .take(frames.len().saturating_sub(1))
                    .map(|f| {
                        let stem = f
                            .file_stem()
                            .map(|s| s.to_string_lossy().into_owned())
                            .unwrap_or_default();
                        (
                            a.out.join(format!("{stem}.flo")),
                            a.viz.as_ref().map(|v| v.join(format!("{stem}.png"))),
                        )
                    })
                    .collect();
                (frames, outputs)
            }
            (None, Some(i1), Some(i2)) => (
                vec![i1.clone(), i2.clone()],
                vec![(a.out.clone(), a.viz.clone())],
            ),
            _ => bail!("give either --img1 and --img2, or --frames DIR"),
        };
    let refine = pins::flow::refine::Refine::parse(&a.refine)?;
    let predictor = Predictor::load_on(&a.weights, pins::flow::device::select(&a.device)?)?
        .with_refine(&refine)
        .with_coarse_start(pins::flow::infer::parse_start(&a.start)?);
    let weights_iters = predictor.config.iters;
    let (iters, stop_px) = a
        .iters
        .map_or((weights_iters, None), |n| n.resolve(weights_iters));
    let video = pins::flow::video::VideoOptions {
        reuse: !a.no_reuse,
        warm_start: a.warm_start,
        stop_px,
    };
    for pair in pair_flows_scaled(&predictor, frames.as_slice(), iters, a.scale, video)? {
        let pair = pair?;
        let (flow, (out, viz)) = (&pair.flow, &outputs[pair.index]);
        io::write_flow(out, flow)?;
        if let Some(v) = viz {
            io::write_image(v, &flow_to_image(flow, None), BitDepth::Eight)?;
        }
        println!(
            "{} → {}: {}x{}, max |flow| {:.2} px, {} iterations, {:.0} ms",
            frames[pair.index].display(),
            out.display(),
            flow.width(),
            flow.height(),
            flow.max_magnitude(),
            pair.iters,
            pair.ms
        );
    }
    Ok(())
}

pub(crate) fn eval(a: EvalArgs) -> Result<()> {
    use pins::flow::{data::FlowDataset, eval::evaluate, infer::Predictor};
    if a.iters.iter().any(|&n| n == 0 || n > 256) {
        bail!("--iters values must be 1..=256");
    }
    let data = FlowDataset::open(&a.data)?;
    data.check_has_known_flow()?;
    let refine = pins::flow::refine::Refine::parse(&a.refine)?;
    let predictor = Predictor::load_on(&a.weights, pins::flow::device::select(&a.device)?)?
        .with_refine(&refine)
        .with_coarse_start(pins::flow::infer::parse_start(&a.start)?);
    let report = evaluate(&predictor, &data, &a.iters)?;
    print!("{}", report.markdown());
    if let Some(out) = &a.out {
        let text = serde_json::to_string_pretty(&report)?;
        io::write_bytes_atomic(out, text.as_bytes())?;
        let png = out.with_extension("png");
        pins::report::eval_plot::write(&report, a.peers.as_deref(), &png)?;
        println!("{} and {}", out.display(), png.display());
    }
    Ok(())
}

pub(crate) fn bench_flow(a: BenchFlowArgs) -> Result<()> {
    if a.reps == 0 || a.iters == 0 {
        bail!("--reps and --iters must be positive");
    }
    if a.mode == "refine" {
        let Some(cfg) = pins::flow::refine::Refine::parse(&a.refine)?.config() else {
            bail!("bench-flow --mode refine needs a refinement, not --refine none");
        };
        let row = pins::report::refine_bench::run(
            a.height,
            a.width,
            a.reps,
            &cfg,
            a.pair_out.as_deref(),
        )?;
        println!("{}", serde_json::to_string(&row)?);
        return Ok(());
    }
    let device = pins::flow::device::select(&a.device)?;
    if a.mode == "kernels" {
        if !matches!(a.device.as_str(), "cpu" | "flex") {
            bail!("--mode kernels times the host kernels: use --device cpu");
        }
        let report =
            pins::report::kernel_bench::run(&a.model, a.height, a.width, a.iters, a.reps, &device)?;
        println!("{}", report.markdown());
        println!("{}", serde_json::to_string(&report)?);
        return Ok(());
    }
    let row = pins::report::flow_bench::run(
        &a.model, &a.mode, a.height, a.width, a.iters, a.reps, &device,
    )?;
    println!("{}", serde_json::to_string(&row)?);
    Ok(())
}

pub(crate) fn bench_real(a: BenchRealArgs) -> Result<()> {
    use pins::report::bench_real::{BenchOptions, run, write_outputs};
    let opts = BenchOptions {
        weights: a.weights.clone(),
        iters: a.iters.clone(),
        peers: !a.no_peers,
        python: a.python.clone(),
        device: pins::flow::device::select(&a.device)?,
        refine: pins::flow::refine::Refine::parse(&a.refine)?,
        coarse_start: pins::flow::infer::parse_start(&a.start)?,
    };
    let started = std::time::Instant::now();
    let report = run(&a.config, &a.out, &opts, &|line| eprintln!("{line}"))?;
    let command: Vec<String> = std::env::args()
        .skip(1)
        .map(|s| {
            if s.contains(char::is_whitespace) {
                format!("'{s}'")
            } else {
                s
            }
        })
        .collect();
    let files = write_outputs(&report, &a.out, &format!("pins {}", command.join(" ")))?;
    for f in files {
        println!("{}", f.display());
    }
    eprintln!(
        "{} runs ({} sets skipped) in {:.0} s",
        report.runs.len(),
        report.skipped.len(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

pub(crate) fn bench_live(a: BenchLiveArgs) -> Result<()> {
    use pins::report::bench_live::{LiveBenchConfig, charts, markdown, run};
    let mut cfg = LiveBenchConfig::from_file(&a.config)?;
    if a.no_peers {
        cfg.dis.clear();
    }
    let device = pins::flow::device::select(&a.device)?;
    let rows = run(&cfg, &a.python, &device, &|line| eprintln!("{line}"))?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let command: Vec<String> = std::env::args().skip(1).collect();
    let md = format!(
        "# bench-live\n\n`pins {}`\n\n{}",
        command.join(" "),
        markdown(&rows)
    );
    let json = serde_json::json!({"config": cfg, "rows": rows});
    io::write_bytes_atomic(
        &a.out.join("report.json"),
        serde_json::to_string_pretty(&json)?.as_bytes(),
    )?;
    io::write_bytes_atomic(&a.out.join("report.md"), md.as_bytes())?;
    for (name, chart) in charts(&rows) {
        chart.write_png(&a.out.join(name), 900, 600)?;
    }
    print!("{}", markdown(&rows));
    Ok(())
}

pub(crate) fn detect_limits(a: DetectLimitsArgs) -> Result<()> {
    use pins::flow::infer::Predictor;
    use pins::report::detection_limits as limits;
    let mut cfg = match &a.config {
        Some(p) => limits::LimitsConfig::from_file(p)?,
        None => limits::LimitsConfig::default(),
    };
    if let Some(iters) = &a.iters {
        cfg.iters = iters.clone();
    }
    cfg.validate()?;
    let predictor = Predictor::load_on(&a.weights, pins::flow::device::select(&a.device)?)?
        .with_refine(&pins::flow::refine::Refine::parse(&a.refine)?)
        .with_coarse_start(pins::flow::infer::parse_start(&a.start)?);
    let runs = limits::run(&cfg, &predictor)?;
    let scores: Vec<_> = runs.iter().flat_map(|r| r.scores.clone()).collect();
    let table = limits::markdown(&scores, &cfg);
    print!("{table}");
    std::fs::create_dir_all(&a.out)?;
    let json = serde_json::json!({"config": cfg, "weights": a.weights, "refine": a.refine, "start": a.start, "scores": scores});
    io::write_bytes_atomic(
        &a.out.join("report.json"),
        serde_json::to_string_pretty(&json)?.as_bytes(),
    )?;
    io::write_bytes_atomic(&a.out.join("report.md"), table.as_bytes())?;
    let fig = a.out.join("fig_s10.png");
    io::write_image(&fig, &limits::figure(&runs), BitDepth::Eight)?;
    println!("{}", fig.display());
    Ok(())
}
