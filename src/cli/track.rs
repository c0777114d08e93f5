//! The tracking commands: track (from flows or frames), render, eval, experiment.

use std::path::{Path, PathBuf};

use anyhow::{Result, bail};

use pins::flow::sequence::pair_flows_scaled;
use pins::io;
use pins::scene::truth::Truth;
use pins::track::photometric::{GreyFrame, GreyPair};
use pins::track::run::Tracks;
use pins::track::still_background::PlaceConfig;

#[derive(clap::Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub(crate) struct TrackArgs {
    #[command(subcommand)]
    cmd: Option<TrackCmd>,
    #[command(flatten)]
    run: RunArgs,
}

#[derive(clap::Subcommand)]
enum TrackCmd {
    /// Render a trajectory clip through the camera: frames/, flows/, truth.json.
    Render(RenderArgs),
    /// Score a tracks.json against a truth.json: RMSE_X, RMSE_Y, RMSE_2D per horizon and ID.
    Eval(EvalArgs),
    /// Run a tracking experiment (clips × predictors, e.g. Table S5 or Note S14).
    Experiment(ExperimentArgs),
}

#[derive(clap::Args)]
struct RunArgs {
    /// Folder of .flo files (flow from frame n to n + 1), in frame order by name.
    #[arg(long)]
    flows: Option<PathBuf>,
    /// Folder of frames, in order by name: flow is estimated by the MMS network (or, with
    /// --flows, read from there); the frames also feed the photometric test.
    #[arg(long)]
    frames: Option<PathBuf>,
    /// MMS weights for --frames: a file, or the built-in mms-small (stage 3, the default here), mms-small-real or default (= mms-small-real).
    #[arg(long, default_value = pins::flow::infer::TRACK_WEIGHTS)]
    weights: String,
    /// Device of the MMS network: cpu, or a GPU backend of this build (wgpu[:N], cuda[:N]).
    #[arg(long, default_value = "cpu")]
    device: String,
    /// MMS refinement iterations for --frames (default: the weights' own).
    #[arg(long)]
    iters: Option<usize>,
    /// What follows MMS: none, variational (the coarse-to-fine variational refinement) or a
    /// .json file of its settings. None by default here: on the tracking clips the refinement
    /// pulls a small, dark mover's flow towards its background (docs/tracking.md).
    #[arg(long, default_value = "none")]
    refine: String,
    /// Where MMS starts: zero (the default here, as the tracking clips were measured) or
    /// coarse (from its own flow at half resolution).
    #[arg(long, default_value = "zero")]
    start: String,
    /// With --frames: run MMS at this multiple of the frame size, in (0, 4]: below 1 faster,
    /// above 1 (frames interpolated) small movers are seen larger, at the square of the scale
    /// in time. The flow is resampled to the full frame, so tracks stay in its pixels.
    #[arg(long, default_value_t = 1.0)]
    scale: f64,
    /// Output folder (tracks.json and one plot per object).
    #[arg(long, required = true)]
    out: Option<PathBuf>,
    /// Predictor: the polynomial fit of Note S13, the constant-velocity baseline, or, per
    /// horizon, whichever of the two forecast this track clearly better over its recent past.
    /// Default: select where the samples are measured on the frames (MMS from --frames, or
    /// --align / --place on), poly (the paper's) otherwise.
    #[arg(long, value_enum)]
    method: Option<Method>,
    /// Fitting window L in frames.
    #[arg(long, default_value_t = 30)]
    window: usize,
    /// Polynomial order n.
    #[arg(long, default_value_t = 2)]
    order: usize,
    /// A fit of order k waits for min(L, this × k + 1) samples, with a lower order until then,
    /// so a new track's few noisy samples are not extrapolated by a quadratic; 1: the highest
    /// order the samples determine (the paper's). Default: 5 where the samples are measured on
    /// the frames (--align or --place on, as for MMS), 1 for a given flow's own.
    #[arg(long)]
    samples_per_order: Option<usize>,
    /// The fitted trend of speed and direction is followed for this many times the fit
    /// window's time span past the last sample, then the velocity is held, so a young track's
    /// few frames are not extrapolated 30 ahead; 0 follows it all the way (the paper's).
    /// Default: 1 where the samples are measured on the frames (--align or --place on, as for
    /// MMS), 0 for a given flow's own.
    #[arg(long)]
    trend_reach: Option<f64>,
    /// Kalman measurement noise of a region's centroid (px²); the default suits the flow
    /// source (see `pins track --help` of --change-test).
    #[arg(long)]
    position_r: Option<f64>,
    /// Kalman measurement noise of a region's speed and direction.
    #[arg(long)]
    motion_r: Option<f64>,
    /// Measurement noise (px²/frame²) of the motion the frames confirm (--align) as the
    /// velocity of the filter the forecasts start from (the tracking filter's velocity is the
    /// flow's); `none` starts them from the tracking filter's centre [default: 0.25]
    #[arg(long, value_parser = parse_aligned_motion_r)]
    aligned_motion_r: Option<AlignedMotionR>,
    /// Samples of the speed and direction fits: the region's flow (the paper's), the
    /// position filter's velocity (which placed centroids correct where the flow
    /// underestimates a small mover), or `auto`: the filter's where the region was placed on
    /// the frame (--place), the flow's elsewhere.
    #[arg(long, value_enum, default_value = "auto")]
    motion_source: MotionSourceArg,
    /// Prediction horizons in frames.
    #[arg(long, value_delimiter = ',', default_value = "1,15,30")]
    horizons: Vec<usize>,
    /// Flow magnitude (px/frame) above which a pixel is moving.
    #[arg(long, default_value_t = 0.5)]
    threshold: f64,
    /// Smallest region (pixels) that is an object.
    #[arg(long, default_value_t = 20)]
    min_area: usize,
    /// Without the change test: raise the threshold to the median flow magnitude plus K
    /// robust standard deviations in frames where the flow jitters (estimated flow); 0 turns
    /// it off.
    #[arg(long, default_value_t = 3.0)]
    noise_k: f64,
    /// Background-motion model fitted and subtracted before the threshold.
    #[arg(long, value_enum, default_value = "affine")]
    background: Background,
    /// Let the change and photometric tests use the fitted background motion even where the
    /// frames do not support it (by default, with frames, they then take the background as
    /// still: an estimated flow's global bias on a still scene is not the camera's motion).
    #[arg(long)]
    no_background_check: bool,
    /// Turn off the photometric test (it runs whenever frames are given).
    #[arg(long)]
    no_photometric: bool,
    /// The change test (with frames): a pixel moves only where the frames changed beyond
    /// their noise, and each such seed grows to its object by the motion the frames confirm,
    /// instead of the flow-noise floor of --noise-k. `auto`: on when MMS estimates the flow
    /// here, off for --flows (turn it on for estimated flows read from files).
    #[arg(long, value_enum, default_value = "auto")]
    change_test: AutoSwitch,
    /// Change test: the frames' noise floor is their averaged difference's median plus this
    /// many robust standard deviations.
    #[arg(long, default_value_t = 4.0)]
    change_k: f64,
    /// Placement on the frame (with frames, while the camera is still): each accepted
    /// region's centroid moves to where frame n differs from the temporal median of the last
    /// frames near it, the object rather than the flow's blob. `auto`: on when MMS estimates
    /// the flow here, off for --flows (turn it on for estimated flows read from files).
    #[arg(long, value_enum, default_value = "auto")]
    place: AutoSwitch,
    /// Alignment (with frames): each accepted region's motion is the translation that best
    /// maps its colours onto the next frame, searched around its mean flow, where that
    /// explains the frames better (an estimated flow falls short on small movers); the
    /// trajectory fits' speed and direction samples take it. `auto`: on when MMS estimates
    /// the flow here, off for --flows (turn it on for estimated flows read from files).
    #[arg(long, value_enum, default_value = "auto")]
    align: AutoSwitch,
    /// Alignment: the weights of the R, G and B residuals, e.g. `1,1,1` for a camera whose
    /// channels are equally sharp. The default, 0.25,1,0.25, puts green first: the metalens
    /// PSF is sharp in green and broad in red and blue, whose halo of a small mover's still
    /// surroundings makes the match fall short.
    #[arg(long, value_delimiter = ',', num_args = 1)]
    align_weights: Option<Vec<f64>>,
    /// Placement: frames in the background's temporal median.
    #[arg(long, default_value_t = 30)]
    place_frames: usize,
    /// Placement: weigh frame n's colour difference from the background in 8-bit levels, not
    /// in the camera's noise at each pixel's level (the default, measured on the still
    /// background: a mover over a dark, quiet part of it counts as surely as over a bright,
    /// noisy one).
    #[arg(long)]
    place_levels: bool,
    /// Placement: a region over the predictions of two or more confirmed tracks (their objects
    /// met in the flow) is split between them where the frame's foreground shows an object
    /// near each prediction, at least this share of the sum of their radii apart; 0 turns the
    /// split off (the tracks on the region coast until it splits in the flow).
    #[arg(long, default_value_t = 0.5)]
    split_separation: f64,
    /// Change test: do not trim from each grown region the pixels that the background's
    /// motion explains better than the region's (the halo of an estimated flow).
    #[arg(long)]
    no_trim: bool,
    /// Photometric test: a region passes when its warp residual with its own flow is at most
    /// this fraction of the residual with the background's motion.
    #[arg(long, default_value_t = 0.8)]
    max_residual_ratio: f64,
    /// With the alignment on: do not retry a region that fails the photometric test with the
    /// motion the frames confirm (such a region, accepted, continues a confirmed track but
    /// starts none).
    #[arg(long)]
    no_retry_aligned: bool,
    /// Confirmation window: consecutive detections, moving as their flow says (or, with
    /// `--align on`, as the motion the frames confirm says), before a track is reported.
    #[arg(long, default_value_t = 5)]
    confirm: usize,
    /// Confirmation: the centre may move up to this many times the sum of its flows, in
    /// their direction (for a flow that underestimates small movers); 1 asks the flow to be
    /// right within 2 px + 30 %.
    #[arg(long, default_value_t = 1.0)]
    consistency_max_ratio: f64,
    /// The matching gate (40 px) widens by half per frame a track has coasted, up to this many
    /// times; 1 keeps it fixed (for a flow that seldom loses its movers, e.g. `--scale 1.5`).
    #[arg(long, default_value_t = 2.0)]
    max_gate_factor: f64,
    /// Report a track that has coasted (no detection) for up to this many frames; longer
    /// coasts stay internal, so the ID survives a gap of up to 15 frames. 0 (the default, as
    /// SORT does) reports only the tracks a detection confirmed in that frame.
    #[arg(long, default_value_t = 0)]
    max_coast_reported: usize,
    /// A matched region smaller than this fraction of its track's median area is a fragment
    /// of the object: the track stays alive but coasts (0 turns this off).
    #[arg(long, default_value_t = 0.35)]
    partial_area_ratio: f64,
    /// Appearance cue (with frames): a region whose colour lies more than this many standard
    /// deviations from a track's running colour is not matched to it (`inf` turns the gate
    /// off).
    #[arg(long, default_value_t = 6.0)]
    appearance_k: f64,
    /// Appearance cue: matching cost (px) per standard deviation of colour difference (0 turns
    /// it off).
    #[arg(long, default_value_t = 5.0)]
    appearance_px: f64,
    /// A region the still background could not place (the foreground's centre too far from
    /// its flow centroid) is placed there after all when that centre lies nearer the track's
    /// prediction, within this share of the region's radius of it (0 turns this off).
    #[arg(long, default_value_t = 0.5)]
    foreground_gate: f64,
    /// Matching cascade (DeepSORT's): confirmed tracks take their detections first, tentative
    /// ones the detections left, so a track born on a fragment cannot push a confirmed track
    /// onto a farther detection.
    #[arg(long)]
    match_cascade: bool,
    /// Re-identification: an ended track's ID waits this many frames after it was last seen
    /// for a new track of its colour born where its object could be (0 turns it off).
    #[arg(long, default_value_t = 150)]
    reid_frames: usize,
    /// Re-identification: the new track's mean colour within this many of the old track's
    /// standard deviations.
    #[arg(long, default_value_t = 3.0)]
    reid_k: f64,
    /// Weak detections (regions that passed the photometric test only with the motion the
    /// frames confirm) continue confirmed tracks only, not tentative ones (ByteTrack's rule).
    #[arg(long)]
    weak_confirmed_only: bool,
    /// Write every frame's regions, their verdicts and reasons to DIR/regions.jsonl.
    #[arg(long)]
    debug: Option<PathBuf>,
    /// Ground truth (truth.json from `pins track render`) to draw in the plots; the
    /// background-flow magnitude of the flows is then measured too.
    #[arg(long)]
    truth: Option<PathBuf>,
    /// Skip the plots.
    #[arg(long)]
    no_plots: bool,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum Background {
    None,
    Translation,
    Affine,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum AutoSwitch {
    /// On when MMS estimates the flow here (--frames alone), off for --flows.
    Auto,
    On,
    Off,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum MotionSourceArg {
    Auto,
    Flow,
    Filter,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum Method {
    Poly,
    ConstantVelocity,
    Select,
}

#[derive(clap::Args)]
struct RenderArgs {
    /// Clip config (scene and camera), e.g. experiments/track_sinusoid.json.
    #[arg(long)]
    config: PathBuf,
    #[arg(long)]
    out: PathBuf,
}

#[derive(clap::Args)]
struct EvalArgs {
    /// tracks.json from `pins track`.
    #[arg(long)]
    tracks: PathBuf,
    /// truth.json from `pins track render`.
    #[arg(long)]
    truth: PathBuf,
    /// Folder of the estimated flows that were tracked: their background-flow magnitude over
    /// the truly static pixels is reported too.
    #[arg(long)]
    flows: Option<PathBuf>,
    /// Also write the report as JSON here.
    #[arg(long)]
    out: Option<PathBuf>,
}

#[derive(clap::Args)]
struct ExperimentArgs {
    #[arg(long)]
    config: PathBuf,
    /// Output folder: report.json, report.txt and plots/.
    #[arg(long)]
    out: PathBuf,
    /// Skip the plots.
    #[arg(long)]
    no_plots: bool,
}

pub(crate) fn track(a: TrackArgs) -> Result<()> {
    match a.cmd {
        Some(TrackCmd::Render(r)) => render(r),
        Some(TrackCmd::Eval(e)) => eval(e),
        Some(TrackCmd::Experiment(e)) => experiment(e),
        None => run(a.run),
    }
}

fn run(a: RunArgs) -> Result<()> {
    use pins::track::{
        background::BackgroundModel,
        detect::DetectConfig,
        mtp::{self, MtpConfig},
        multi::TrackerConfig,
        run as tr,
    };
    let Some(out) = a.out else {
        bail!("--out is required")
    };
    let tracker = TrackerConfig {
        mtp: MtpConfig {
            method: a.method.map(|m| match m {
                Method::Poly => mtp::Method::Poly,
                Method::ConstantVelocity => mtp::Method::ConstantVelocity,
                Method::Select => mtp::Method::Select,
            }),
            window: a.window,
            order: a.order,
            samples_per_order: a.samples_per_order,
            trend_reach: a.trend_reach,
            position_r: a.position_r.unwrap_or(MtpConfig::default().position_r),
            motion_r: a.motion_r.unwrap_or(MtpConfig::default().motion_r),
            aligned_motion_r: match a.aligned_motion_r {
                Some(AlignedMotionR(r)) => r,
                None => MtpConfig::default().aligned_motion_r,
            },
            motion_source: match a.motion_source {
                MotionSourceArg::Auto => mtp::MotionSource::Auto,
                MotionSourceArg::Flow => mtp::MotionSource::Flow,
                MotionSourceArg::Filter => mtp::MotionSource::Filter,
            },
            ..MtpConfig::default()
        },
        confirm: a.confirm,
        consistency_max_ratio: a.consistency_max_ratio,
        max_gate_factor: a.max_gate_factor,
        partial_area_ratio: a.partial_area_ratio,
        max_coast_reported: a.max_coast_reported,
        appearance_k: a.appearance_k,
        appearance_px: a.appearance_px,
        match_cascade: a.match_cascade,
        foreground_gate: a.foreground_gate,
        reid_frames: a.reid_frames,
        reid_k: a.reid_k,
        weak_continues_tentative: !a.weak_confirmed_only,
        ..TrackerConfig::default()
    };
    tracker.mtp.validate()?;
    if a.confirm == 0 {
        bail!("--confirm must be >= 1");
    }
    if !(1..=255).contains(&a.place_frames) {
        bail!("--place-frames must be 1..=255, got {}", a.place_frames);
    }
    let align_weights = match a.align_weights.as_deref() {
        None => pins::track::align::ALIGN_WEIGHTS,
        Some(&[r, g, b]) => [r, g, b],
        Some(w) => bail!(
            "--align-weights takes three weights (R,G,B), got {}",
            w.len()
        ),
    };
    let detect = DetectConfig {
        align_weights,
        background: match a.background {
            Background::None => BackgroundModel::None,
            Background::Translation => BackgroundModel::Translation,
            Background::Affine => BackgroundModel::Affine,
        },
        check_background: !a.no_background_check,
        photometric: !a.no_photometric,
        max_residual_ratio: a.max_residual_ratio,
        change: match a.change_test {
            AutoSwitch::Auto => None,
            AutoSwitch::On => Some(true),
            AutoSwitch::Off => Some(false),
        },
        change_k: a.change_k,
        trim: !a.no_trim,
        retry_aligned: !a.no_retry_aligned,
        align: match a.align {
            AutoSwitch::Auto => None,
            AutoSwitch::On => Some(true),
            AutoSwitch::Off => Some(false),
        },
        place: PlaceConfig {
            enabled: match a.place {
                AutoSwitch::Auto => None,
                AutoSwitch::On => Some(true),
                AutoSwitch::Off => Some(false),
            },
            frames: a.place_frames,
            min_frames: PlaceConfig::default().min_frames.min(a.place_frames.max(1)),
            split: a.split_separation,
            pixel_noise: !a.place_levels,
            ..PlaceConfig::default()
        },
        ..DetectConfig::default()
    };
    detect.validate()?;
    if !(a.noise_k.is_finite() && a.noise_k >= 0.0) {
        bail!("--noise-k must be finite and >= 0, got {}", a.noise_k);
    }
    let opts = tr::TrackOptions {
        tracker,
        horizons: a.horizons,
        threshold: a.threshold,
        noise_k: a.noise_k,
        min_area: a.min_area,
        detect: detect.resolved(a.flows.is_none()),
        debug: a.debug.is_some(),
    };
    // Read the truth first so a bad file fails before any work.
    let truth = a.truth.as_deref().map(Truth::read).transpose()?;
    let (run, frames, flow_ms) = match (&a.flows, &a.frames) {
        (Some(dir), frames) => {
            let files = tr::flow_files(dir)?;
            let images = frames.as_deref().map(io::frame_files).transpose()?;
            let run = tr::track_flows(&files, images.as_deref(), &opts, truth.as_ref())?;
            (run, files.len(), None)
        }
        (None, Some(dir)) => {
            pins::flow::scale::check_scale(a.scale)
                .map_err(|_| anyhow::anyhow!("--scale must be in (0, 4], got {}", a.scale))?;
            let files = io::frame_files(dir)?;
            let predictor = pins::flow::infer::Predictor::load_on(
                &a.weights,
                pins::flow::device::select(&a.device)?,
            )?
            .with_refine(&pins::flow::refine::Refine::parse(&a.refine)?)
            .with_coarse_start(pins::flow::infer::parse_start(&a.start)?);
            let iters = a.iters.unwrap_or(predictor.config.iters);
            let mut flow_ms = 0.0;
            let mut prev: Option<GreyFrame> = None;
            let flows = pair_flows_scaled(&predictor, files.as_slice(), iters, a.scale).map(|p| {
                let p = p?;
                flow_ms += p.ms;
                let first = match prev.take() {
                    Some(g) => g,
                    None => GreyFrame::new(&io::read_image(&files[p.index])?),
                };
                let second = GreyFrame::new(&io::read_image(&files[p.index + 1])?);
                let pair = GreyPair::of(&first, &second);
                prev = Some(second);
                Ok(tr::FlowStep {
                    name: files[p.index].display().to_string(),
                    flow: p.flow,
                    frames: pair,
                })
            });
            let run = tr::track_sequence(flows, &opts, truth.as_ref())?;
            let n = files.len() - 1;
            (run, n, Some(flow_ms / n as f64))
        }
        _ => bail!("give either --flows DIR or --frames DIR"),
    };
    let tracks = run.tracks;
    if let Some(dir) = &a.debug {
        std::fs::create_dir_all(dir)?;
        let mut text = String::new();
        for f in &run.debug {
            text += &serde_json::to_string(f)?;
            text.push('\n');
        }
        io::write_bytes_atomic(&dir.join("regions.jsonl"), text.as_bytes())?;
    }
    // Plots first: tracks.json, written last, marks a finished run.
    if !a.no_plots {
        std::fs::create_dir_all(&out)?;
        plots(&out, &tracks, truth.as_ref(), &opts.horizons)?;
    }
    let path = out.join("tracks.json");
    io::write_bytes_atomic(&path, serde_json::to_string_pretty(&tracks)?.as_bytes())?;
    let ms = tracks.ms_per_frame.unwrap_or(f64::NAN);
    print!(
        "{}: {} objects over {frames} flows, tracking {ms:.2} ms per frame",
        path.display(),
        tracks.objects.len(),
    );
    match flow_ms {
        Some(f) => println!(", MMS flow {f:.0} ms per frame"),
        None => println!(),
    }
    if let Some(b) = &tracks.background_flow {
        println!(
            "background flow over static pixels: mean {:.3} px, p99 {:.3} px, max {:.2} px",
            b.mean, b.p99, b.max
        );
    }
    Ok(())
}

/// One Fig. S11 plot per object at the longest horizon, `plot_id{ID}.png`. With a truth, each
/// track is drawn against the true object it follows.
fn plots(dir: &Path, tracks: &Tracks, truth: Option<&Truth>, horizons: &[usize]) -> Result<()> {
    use pins::report::track_plot::plot_track;
    let k = horizons.iter().copied().max().unwrap_or(1);
    let matched = match truth {
        Some(t) => pins::track::eval::evaluate(tracks, t)?
            .objects
            .iter()
            .map(|o| o.truth_index)
            .collect(),
        None => vec![None; tracks.objects.len()],
    };
    let size = match truth {
        Some(t) => (t.width, t.height),
        None => extent(tracks),
    };
    let fps = truth.map_or(30.0, |t| t.fps);
    for (t, m) in tracks.objects.iter().zip(matched) {
        let obj = truth.zip(m).map(|(tr, i)| &tr.objects[i]);
        plot_track(
            &dir.join(format!("plot_id{}.png", t.id)),
            t,
            k,
            obj,
            size,
            fps,
        )?;
    }
    Ok(())
}

/// A frame size covering every tracked centre (when no truth gives the real one).
fn extent(tracks: &Tracks) -> (usize, usize) {
    let (mut w, mut h) = (1.0f64, 1.0f64);
    for f in tracks.objects.iter().flat_map(|o| &o.frames) {
        w = w.max(f.centroid[0] * 1.1);
        h = h.max(f.centroid[1] * 1.1);
    }
    (w.ceil() as usize, h.ceil() as usize)
}

fn render(a: RenderArgs) -> Result<()> {
    use pins::dataset::sequence::{SequenceConfig, render_sequence};
    let cfg = SequenceConfig::from_file(&a.config)?;
    let started = std::time::Instant::now();
    let truth = render_sequence(&cfg, &a.out)?;
    println!(
        "{}: {} frames of {}x{}, {} objects, {:.1} s",
        a.out.display(),
        truth.frames,
        truth.width,
        truth.height,
        truth.objects.len(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

fn eval(a: EvalArgs) -> Result<()> {
    use pins::track::eval::{evaluate, table};
    let tracks = Tracks::read(&a.tracks)?;
    let truth = Truth::read(&a.truth)?;
    let mut report = evaluate(&tracks, &truth)?;
    if let Some(dir) = &a.flows {
        let files = pins::track::run::flow_files(dir)?;
        report.background_flow = pins::track::run::background_flow(&files, &truth)?;
    }
    println!("{}", table(&report));
    if let Some(out) = a.out {
        io::write_bytes_atomic(&out, serde_json::to_string_pretty(&report)?.as_bytes())?;
    }
    Ok(())
}

fn experiment(a: ExperimentArgs) -> Result<()> {
    use pins::report::track_plot::plot_track;
    use pins::track::eval::evaluate;
    use pins::track::experiment::{ExperimentConfig, points_chart, points_table, run, table};
    let cfg = ExperimentConfig::from_file(&a.config)?;
    let k = cfg.horizons.iter().copied().max().unwrap_or(1);
    let plots = a.out.join("plots");
    if !a.no_plots {
        std::fs::create_dir_all(&plots)?;
    }
    let report = run(&cfg, |clip, predictor, tracks, truth| {
        if a.no_plots {
            return Ok(());
        }
        let slug: String = format!("{clip}_{predictor}")
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
            .collect();
        // One plot per true object: the track that follows it (spurious tracks, which a noisy
        // estimated flow can make by the dozen, are scored but not drawn).
        let matched = evaluate(tracks, truth)?;
        for (t, o) in tracks.objects.iter().zip(&matched.objects) {
            let Some(i) = o.truth_index else {
                continue;
            };
            plot_track(
                &plots.join(format!("{slug}_id{}.png", t.id)),
                t,
                k,
                Some(&truth.objects[i]),
                (truth.width, truth.height),
                truth.fps,
            )?;
        }
        Ok(())
    })?;
    let text = table(&report) + &points_table(&report);
    println!("{text}");
    if cfg.operating_points.len() > 1 {
        for &h in &cfg.horizons {
            // A horizon no track reached has no finite error to draw: said, not fatal.
            if let Some(chart) = points_chart(&report, h) {
                let png = a.out.join(format!("error_vs_ms_h{h}.png"));
                if let Err(e) = chart.write_png(&png, 900, 600) {
                    eprintln!("{}: not written: {e}", png.display());
                }
            }
        }
    }
    io::write_bytes_atomic(
        &a.out.join("report.json"),
        serde_json::to_string_pretty(&report)?.as_bytes(),
    )?;
    io::write_bytes_atomic(&a.out.join("report.txt"), text.as_bytes())?;
    Ok(())
}

/// `--aligned-motion-r`: a variance, or `none`.
#[derive(Clone, Copy, Debug)]
struct AlignedMotionR(Option<f64>);

fn parse_aligned_motion_r(s: &str) -> std::result::Result<AlignedMotionR, String> {
    if s == "none" {
        return Ok(AlignedMotionR(None));
    }
    match s.parse::<f64>() {
        Ok(r) if r.is_finite() && r > 0.0 => Ok(AlignedMotionR(Some(r))),
        _ => Err(format!("expected a variance > 0 or `none`, got {s:?}")),
    }
}
