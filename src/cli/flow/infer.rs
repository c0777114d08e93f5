//! `pins infer` and `pins eval`: flow from trained weights (Notes S9–S10) for a pair or a
//! folder of frames, and its scores on a dataset with ground truth.

use std::path::PathBuf;

use anyhow::{Result, bail};

use pins::io::{self, BitDepth};

#[derive(clap::Args)]
pub(crate) struct InferArgs {
    /// Weights file, or built-in weights: default (= mms-small-real, the training campaign's shipped weights), mms-small (stage 3).
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
    /// Weights file, or built-in weights: default (= mms-small-real, the training campaign's shipped weights), mms-small (stage 3).
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
