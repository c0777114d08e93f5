//! The flow benchmarks: `pins bench-flow` (timing), `bench-real` (real pairs against DIS),
//! `bench-live` (the live system's error against run time) and `detect-limits` (Note S12).

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
    /// Weights file, or built-in weights: default (= mms-small-real, the training campaign's shipped weights), mms-small (stage 3).
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
