//! The tracking commands: track (from flows or frames), render, eval, experiment.

use std::path::{Path, PathBuf};

use anyhow::{Result, bail};

use pins::flow::sequence::pair_flows_scaled;
use pins::io;
use pins::scene::truth::Truth;
use pins::track::config::{Profile, TrackConfig};
use pins::track::detect::photometric::{GreyFrame, GreyPair};
use pins::track::tracker::tracks::Tracks;

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
    /// Tracking settings (a JSON TrackConfig: a profile and the keys it changes, e.g.
    /// experiments/track_config_estimated.json); the flags below override it.
    #[arg(long)]
    config: Option<PathBuf>,
    /// The defaults for a given flow (exact) or an estimated one. Default: the config's, else
    /// estimated for --frames alone (MMS estimates the flow), exact for --flows.
    #[arg(long)]
    profile: Option<Profile>,
    /// Folder of .flo files (flow from frame n to n + 1), in frame order by name.
    #[arg(long)]
    flows: Option<PathBuf>,
    /// Folder of frames, in order by name: flow is estimated by the MMS network (or, with
    /// --flows, read from there); the frames also feed the photometric test.
    #[arg(long)]
    frames: Option<PathBuf>,
    /// Output folder (tracks.json and one plot per object).
    #[arg(long, required = true)]
    out: Option<PathBuf>,
    /// Ground truth (truth.json from `pins track render`) to draw in the plots; the
    /// background-flow magnitude of the flows is then measured too.
    #[arg(long)]
    truth: Option<PathBuf>,
    /// Write every frame's regions, their verdicts and reasons to DIR/regions.jsonl.
    #[arg(long)]
    debug: Option<PathBuf>,
    /// Skip the plots.
    #[arg(long)]
    no_plots: bool,
    /// Device of the MMS network: cpu, or a GPU backend of this build (wgpu[:N], cuda[:N]).
    #[arg(long, default_value = "cpu")]
    device: String,
    /// MMS weights for --frames (flow.weights): a file, or the built-in mms-small-real (the
    /// default), default (= mms-small-real) or mms-small.
    #[arg(long)]
    weights: Option<String>,
    /// MMS refinement iterations (flow.iters): a count, or auto (at most the weights' own,
    /// stopping once the flow settles); default: the weights' own.
    #[arg(long)]
    iters: Option<pins::flow::iters::Iters>,
    /// Start each pair's MMS from the previous pair's flow, carried forward (flow.warm_start).
    #[arg(long)]
    warm_start: bool,
    /// Encode every frame twice, as the first and second of its pairs (flow.reuse false): the
    /// same flow, slower.
    #[arg(long)]
    no_reuse: bool,
    /// With --frames: run MMS at this multiple of the frame size, in (0, 4] (flow.scale;
    /// default: the frame made 1280 px wide, 2 for 640×480, 4 for 320×240): smaller is
    /// faster, but a small mover textured like its background is seen in part. Tracks stay
    /// in the frame's pixels.
    #[arg(long)]
    scale: Option<f64>,
    /// Confirmation window (tracker.confirm; default 5): consecutive detections moving as
    /// their motion says before a track is reported.
    #[arg(long)]
    confirm: Option<usize>,
    /// Prediction horizons in frames (horizons; default 1,15,30).
    #[arg(long, value_delimiter = ',')]
    horizons: Option<Vec<usize>>,
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
    use pins::track::run as tr;
    let Some(out) = a.out.clone() else {
        bail!("--out is required")
    };
    let cfg = settings(&a)?;
    let fallback = if a.flows.is_some() {
        Profile::Exact
    } else {
        Profile::Estimated
    };
    let opts = cfg.options(fallback, a.debug.is_some())?;
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
            let files = io::frame_files(dir)?;
            let predictor = cfg.flow.predictor(pins::flow::device::select(&a.device)?)?;
            let (iters, video) = cfg.flow.iters_for(&predictor);
            let scale = match files.first() {
                Some(f) => cfg.flow.scale_for(io::read_image(f)?.width()),
                None => cfg.flow.scale_for(0),
            };
            let mut flow_ms = 0.0;
            let mut prev: Option<GreyFrame> = None;
            let flows =
                pair_flows_scaled(&predictor, files.as_slice(), iters, scale, video)?.map(|p| {
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
    let text = table(&report) + &points_table(&report.points);
    println!("{text}");
    if cfg.operating_points.len() > 1 {
        for &h in &cfg.horizons {
            // A horizon no track reached has no finite error to draw: said, not fatal.
            if let Some(chart) = points_chart(&report.points, h) {
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

/// The tracking settings: the config file (or the defaults) with the flags' overrides.
fn settings(a: &RunArgs) -> Result<TrackConfig> {
    let mut cfg = match &a.config {
        Some(p) => TrackConfig::from_file(p)?,
        None => TrackConfig::default(),
    };
    if let Some(s) = a.scale {
        cfg.flow.scale = Some(s);
    }
    let flags = Overrides {
        profile: a.profile,
        weights: a.weights.as_deref(),
        iters: a.iters,
        warm_start: a.warm_start,
        no_reuse: a.no_reuse,
        confirm: a.confirm,
        horizons: a.horizons.as_deref(),
    };
    flags.apply(cfg)
}

/// The flags `pins track` and `pins live` both lay over a tracking config.
pub(crate) struct Overrides<'a> {
    pub profile: Option<Profile>,
    pub weights: Option<&'a str>,
    pub iters: Option<pins::flow::iters::Iters>,
    pub warm_start: bool,
    pub no_reuse: bool,
    pub confirm: Option<usize>,
    pub horizons: Option<&'a [usize]>,
}

impl Overrides<'_> {
    /// `cfg` with the flags given laid over it, checked (an error names the flag).
    pub(crate) fn apply(&self, mut cfg: TrackConfig) -> Result<TrackConfig> {
        if let Some(p) = self.profile {
            cfg.profile = Some(p);
        }
        if let Some(w) = self.weights {
            cfg.flow.weights = w.to_string();
        }
        if self.iters.is_some() {
            cfg.flow.iters = self.iters;
        }
        if self.warm_start {
            cfg.flow.warm_start = true;
        }
        if self.no_reuse {
            cfg.flow.reuse = false;
        }
        if let Some(c) = self.confirm {
            cfg.tracker.confirm = c;
        }
        if let Some(h) = self.horizons {
            cfg.horizons = h.to_vec();
        }
        cfg.validate().map_err(flag_named)?;
        Ok(cfg)
    }
}

/// A settings error, with the flag that sets the key where there is one (the file's own
/// values were checked when it was read).
pub(crate) fn flag_named(e: pins::Error) -> anyhow::Error {
    const FLAGS: [(&str, &str); 5] = [
        ("flow.scale", "--scale"),
        ("flow.iters", "--iters"),
        ("flow.weights", "--weights"),
        ("tracker.confirm", "--confirm"),
        ("horizons", "--horizons"),
    ];
    match e {
        pins::Error::Invalid { what, reason } => {
            let flag = FLAGS
                .iter()
                .find(|(k, _)| *k == what)
                .map(|(_, f)| format!(" ({f})"))
                .unwrap_or_default();
            anyhow::anyhow!("invalid {what}{flag}: {reason}")
        }
        e => e.into(),
    }
}
