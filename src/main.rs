//! The `pins` command line: parses flags, calls the library, prints. No logic of its own.

use std::io::IsTerminal;
use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};

use pins::dataset::{Generator, GeneratorConfig, Shard};
use pins::imaging::{Camera, CameraConfig, psf_source};
use pins::io::{self, BitDepth};

/// Metalens motion sensing: camera simulator, flow dataset generator and optics.
#[derive(Parser)]
#[command(name = "pins", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Generate image pairs with exact ground-truth flow through the metalens camera.
    Generate(GenerateArgs),
    /// Apply the metalens camera model to one image.
    Simulate(SimulateArgs),
    /// Compute a metalens PSF by scalar diffraction and compare its spot with the Airy radius.
    Psf(PsfArgs),
    /// Benchmark the camera model: throughput, and direct vs FFT convolution against f64.
    Bench(BenchArgs),
    /// Train the MMS flow network on a dataset from `pins generate`.
    Train(TrainArgs),
    /// Export a training run's weights (safetensors with the model config inside).
    Export(ExportArgs),
    /// Estimate optical flow with trained weights, for one pair or a folder of frames.
    Infer(InferArgs),
    /// Evaluate weights on a dataset: EPE, AE, 1/3/5 px and ms per pair for several iteration counts.
    Eval(EvalArgs),
    /// Time MMS inference or one training step (random weights) and print a JSON line.
    BenchFlow(BenchFlowArgs),
    /// SSIM, MAE and MSE of two images (Note S7).
    Compare(CompareArgs),
    /// Optics calculators: depth of field, detection limits, stereo depth, field of view.
    #[command(subcommand)]
    Optics(OpticsCommand),
    /// The wide-angle 3-lens array: raw frames, calibration, stitching (Note S3).
    #[command(subcommand)]
    Array(ArrayCommand),
    /// Track moving objects through a folder of flow maps and predict their trajectories (Note S13).
    Track(TrackArgs),
}

#[derive(clap::Args)]
struct TrackArgs {
    /// Folder of .flo files, in frame order by name.
    #[arg(long)]
    flows: PathBuf,
    /// Output folder (tracks.json).
    #[arg(long)]
    out: PathBuf,
    /// Fitting window L in frames.
    #[arg(long, default_value_t = 30)]
    window: usize,
    /// Polynomial order n.
    #[arg(long, default_value_t = 2)]
    order: usize,
    /// Prediction horizons in frames.
    #[arg(long, value_delimiter = ',', default_value = "1,15,30")]
    horizons: Vec<usize>,
    /// Flow magnitude (px/frame) above which a pixel is moving.
    #[arg(long, default_value_t = 0.5)]
    threshold: f64,
    /// Smallest region (pixels) that is an object.
    #[arg(long, default_value_t = 20)]
    min_area: usize,
}

#[derive(Subcommand)]
enum ArrayCommand {
    /// Render the raw 1600×1200 sensor frame of an ideal 480×1440 (135°) scene, or of the dot grid.
    Render {
        /// The ideal wide scene (height 480, width 1440 for the default layout).
        #[arg(long = "in")]
        input: Option<PathBuf>,
        /// Render the dot-grid calibration target instead of a scene.
        #[arg(long)]
        grid: bool,
        /// Dots per tile side of the grid.
        #[arg(long, default_value_t = 11)]
        dots: usize,
        #[arg(long)]
        out: PathBuf,
        /// Array layout (JSON); the paper's default when absent.
        #[arg(long)]
        config: Option<PathBuf>,
        /// default: the camera model of the generator (PSF, noise, gamma); none: the ideal frame.
        #[arg(long, default_value = "default")]
        camera: String,
        #[arg(long, default_value_t = 0)]
        seed: u64,
    },
    /// Fit each lens's distortion polynomials from a raw dot-grid frame.
    Calibrate {
        #[arg(long)]
        grid: PathBuf,
        #[arg(long)]
        out: PathBuf,
        #[arg(long)]
        config: Option<PathBuf>,
        #[arg(long, default_value_t = 11)]
        dots: usize,
        /// Polynomial order (2…6); chosen by held-out error when absent.
        #[arg(long)]
        order: Option<usize>,
    },
    /// Reprojection error and stitch time per frame for polynomial orders 2…6.
    Bench {
        #[arg(long)]
        grid: PathBuf,
        #[arg(long)]
        config: Option<PathBuf>,
        #[arg(long, default_value_t = 11)]
        dots: usize,
        #[arg(long, default_value_t = 5)]
        reps: usize,
    },
    /// Rectify and join a raw frame (or a folder of frames) into the 480×1440 image.
    Stitch {
        #[arg(long)]
        calib: PathBuf,
        /// A raw frame, or a folder of raw frames.
        #[arg(long = "in")]
        input: PathBuf,
        /// Output image, or folder when --in is a folder.
        #[arg(long)]
        out: PathBuf,
    },
}

#[derive(clap::Args)]
struct CompareArgs {
    a: PathBuf,
    b: PathBuf,
    /// Print {"ssim", "mae", "mse"} as JSON.
    #[arg(long)]
    json: bool,
}

#[derive(Subcommand)]
enum OpticsCommand {
    /// Depth of field (Eqs. S5–S8, Table S1) for sensor distances v0 = f + offset.
    Dof {
        /// Offsets v0 − f in µm.
        #[arg(long, value_delimiter = ',', default_value = "0,10,15,20,25")]
        offsets_um: Vec<f64>,
        #[arg(long, default_value_t = 1.6)]
        focal_mm: f64,
        #[arg(long, default_value_t = 1.0)]
        diameter_mm: f64,
        #[arg(long, default_value_t = 2.2)]
        pixel_um: f64,
        /// Circle of confusion in pixels.
        #[arg(long, default_value_t = 2.0)]
        coc_pixels: f64,
        #[arg(long)]
        json: bool,
    },
    /// Angular pixel size and the smallest detectable displacement and object (Note S12).
    Resolution {
        #[arg(long, default_value_t = 10.0)]
        distance_m: f64,
        #[arg(long, default_value_t = 2.2)]
        pixel_um: f64,
        #[arg(long, default_value_t = 1.6)]
        focal_mm: f64,
        /// Smallest detectable displacement in pixels (Fig. S10a–c: 3).
        #[arg(long, default_value_t = 3.0)]
        min_shift_px: f64,
        /// Smallest detectable target diameter in pixels (Fig. S10e–g: 5).
        #[arg(long, default_value_t = 5.0)]
        min_target_px: f64,
        #[arg(long)]
        json: bool,
    },
    /// Depth from two image points and a baseline (Eqs. S24–S25).
    Stereo {
        /// Image position in lens 1, mm from its axis.
        #[arg(long, allow_hyphen_values = true)]
        x1_mm: f64,
        /// Image position in lens 2, mm from its axis.
        #[arg(long, allow_hyphen_values = true)]
        x2_mm: f64,
        /// Baseline between the lenses, m.
        #[arg(long)]
        baseline_m: f64,
        #[arg(long, default_value_t = 1.6)]
        focal_mm: f64,
        #[arg(long, value_enum, default_value = "hyperbolic")]
        profile: ProfileArg,
        #[arg(long)]
        json: bool,
    },
    /// Angular sectors, total FoV and overlaps of a tilted array (Note S16), and the focal spot
    /// against the Airy radius across the field of lenses designed for 45° and 80° (Note S2).
    Fov {
        #[arg(
            long,
            value_delimiter = ',',
            default_value = "-45,0,45",
            allow_hyphen_values = true
        )]
        tilts_deg: Vec<f64>,
        #[arg(long, default_value_t = 45.0)]
        fov_deg: f64,
        /// Also sweep the spot size over the field (slow: one diffraction PSF per angle).
        #[arg(long)]
        spots: bool,
        /// FFT grid for the spot sweep (large field angles need a fine grid).
        #[arg(long, default_value_t = 3072)]
        grid: usize,
        #[arg(long)]
        json: bool,
    },
}

#[derive(clap::Args)]
struct BenchFlowArgs {
    /// mms or mms-small.
    #[arg(long, default_value = "mms-small")]
    model: String,
    /// infer (batch 1) or train (batch 2, one AdamW step).
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
}

#[derive(clap::Args)]
struct TrainArgs {
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
    /// Device: cpu, or cuda[:N] in a build with `--features cuda`.
    #[arg(long, default_value = "cpu")]
    device: String,
    /// Start from these weights (fine-tuning) instead of a random initialisation.
    #[arg(long)]
    init: Option<PathBuf>,
    /// Stop after this many steps in this session (a checkpoint is written); continue later
    /// with --resume. The learning-rate schedule still spans the whole run.
    #[arg(long)]
    stop_after: Option<usize>,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

#[derive(clap::Args)]
struct ExportArgs {
    /// Training run folder.
    #[arg(long)]
    run: PathBuf,
    /// Output weights file (.safetensors).
    #[arg(long)]
    out: PathBuf,
}

#[derive(clap::Args)]
struct InferArgs {
    /// Weights file, or "default" for the shipped mms-small weights.
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
    /// Refinement iterations (the model's default when absent).
    #[arg(long)]
    iters: Option<usize>,
    /// Device: cpu, or cuda[:N] in a build with `--features cuda`.
    #[arg(long, default_value = "cpu")]
    device: String,
}

#[derive(clap::Args)]
struct EvalArgs {
    /// Weights file, or "default".
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
    /// Device: cpu, or cuda[:N] in a build with `--features cuda`.
    #[arg(long, default_value = "cpu")]
    device: String,
}

#[derive(clap::Args)]
struct BenchArgs {
    /// Repetitions per measurement (the median is reported).
    #[arg(long, default_value_t = 5)]
    reps: usize,
    /// Thread counts to measure the pipeline with.
    #[arg(long, value_delimiter = ',', default_value = "1,2")]
    threads: Vec<usize>,
    /// PSF sizes for the convolution table (odd).
    #[arg(long, value_delimiter = ',', default_value = "9,17,33,65,129")]
    psf_sizes: Vec<usize>,
    /// Also write the report as JSON.
    #[arg(long)]
    json: Option<PathBuf>,
}

#[derive(clap::Args)]
struct PsfArgs {
    /// Output file: .exr (float), .npy (float) or .png (16-bit, each channel scaled to its peak).
    #[arg(long)]
    out: PathBuf,
    /// Phase profile (Note S2).
    #[arg(long, value_enum, default_value = "hyperbolic")]
    profile: ProfileArg,
    /// Design wavelength in nm.
    #[arg(long, default_value_t = 532.0)]
    design_wavelength: f64,
    /// Field angle of the point source in degrees.
    #[arg(long, default_value_t = 0.0)]
    field_angle: f64,
    /// Linear tilt θt of the phase (k·x·sin θt) in degrees.
    #[arg(long, default_value_t = 0.0)]
    tilt: f64,
    /// Kernel size in sensor pixels (odd).
    #[arg(long, default_value_t = 65)]
    size: usize,
    /// FFT grid size N.
    #[arg(long, default_value_t = 2048)]
    grid: usize,
    /// Lens diameter in mm.
    #[arg(long, default_value_t = 1.0)]
    diameter: f64,
    /// Focal length in mm.
    #[arg(long, default_value_t = 1.6)]
    focal: f64,
    /// Sensor pixel pitch in µm.
    #[arg(long, default_value_t = 2.2)]
    pixel: f64,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum ProfileArg {
    Hyperbolic,
    Quadratic,
}

#[derive(clap::Args)]
struct GenerateArgs {
    /// Generator config (JSON); the shipped defaults when absent.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Output folder.
    #[arg(long, default_value = "out/dataset")]
    out: PathBuf,
    /// Number of samples (overrides the config).
    #[arg(long)]
    count: Option<usize>,
    /// Master seed (overrides the config).
    #[arg(long)]
    seed: Option<u64>,
    /// Generate only shard K of N (K/N, 0-based): a contiguous block of samples.
    #[arg(long, default_value = "0/1")]
    shard: String,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

#[derive(clap::Args)]
struct SimulateArgs {
    /// Input image (PNG 8/16-bit, JPEG, PPM, TIFF, EXR, .npy).
    #[arg(long = "in")]
    input: PathBuf,
    /// Output image (PNG, PPM, TIFF; EXR/.npy keep floats).
    #[arg(long)]
    out: PathBuf,
    /// Camera config (JSON with the keys of the "camera" section); flags override it.
    #[arg(long)]
    config: Option<PathBuf>,
    /// PSF: "default", "delta" or a file (PNG 8/16-bit, EXR, .npy, TIFF).
    #[arg(long)]
    psf: Option<String>,
    /// Shot-noise parameter a (Eq. S3, 8-bit DN).
    #[arg(long)]
    noise_a: Option<f32>,
    /// Read-noise parameter b (Eq. S3, DN²).
    #[arg(long)]
    noise_b: Option<f32>,
    /// Gamma exponent (Eq. S4).
    #[arg(long)]
    gamma: Option<f32>,
    /// Brightness factor.
    #[arg(long)]
    brightness: Option<f32>,
    /// Output bit depth, 8 or 16.
    #[arg(long)]
    bit_depth: Option<u8>,
    /// Noise seed.
    #[arg(long, default_value_t = 0)]
    seed: u64,
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Generate(a) => generate(a),
        Command::Simulate(a) => simulate(a),
        Command::Psf(a) => psf(a),
        Command::Bench(a) => bench(a),
        Command::Train(a) => train(a),
        Command::Export(a) => export(a),
        Command::Infer(a) => infer(a),
        Command::Eval(a) => eval(a),
        Command::BenchFlow(a) => bench_flow(a),
        Command::Compare(a) => compare(a),
        Command::Optics(c) => optics(c),
        Command::Array(c) => array(c),
        Command::Track(a) => track(a),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

fn generate(a: GenerateArgs) -> Result<()> {
    let mut config = match &a.config {
        Some(p) => GeneratorConfig::from_file(p)?,
        None => GeneratorConfig::default(),
    };
    if let Some(n) = a.count {
        config.count = n;
    }
    if let Some(s) = a.seed {
        config.seed = s;
    }
    let shard = Shard::parse(&a.shard)?;
    let generator = Generator::new(config)?;
    let progress = !a.quiet && std::io::stderr().is_terminal();
    let started = std::time::Instant::now();
    let summary = generator
        .run(&a.out, shard, progress)
        .with_context(|| format!("generating into {}", a.out.display()))?;
    let secs = started.elapsed().as_secs_f64();
    println!(
        "{}: {} samples generated, {} kept, in {:.1} s ({:.2} samples/s); camera stages: {}",
        a.out.display(),
        summary.generated,
        summary.kept,
        secs,
        summary.generated as f64 / secs.max(1e-9),
        generator.stage_names().join(" → ")
    );
    if summary.manifest_written {
        println!(
            "{}/manifest.json lists all {} samples",
            a.out.display(),
            summary.total
        );
    } else {
        println!(
            "{} of {} samples complete; manifest.json is written when every shard has finished",
            summary.complete, summary.total
        );
    }
    Ok(())
}

fn simulate(a: SimulateArgs) -> Result<()> {
    let mut cfg = match &a.config {
        Some(p) => {
            let text =
                std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?;
            serde_json::from_str::<CameraConfig>(&text)
                .with_context(|| format!("config {}", p.display()))?
        }
        None => CameraConfig::default(),
    };
    if let Some(v) = a.psf {
        cfg.psf = v;
    }
    if let Some(v) = a.noise_a {
        cfg.noise.a = v;
    }
    if let Some(v) = a.noise_b {
        cfg.noise.b = v;
    }
    if let Some(v) = a.gamma {
        cfg.gamma = v;
    }
    if let Some(v) = a.brightness {
        cfg.brightness = v;
    }
    if let Some(v) = a.bit_depth {
        cfg.bit_depth = v;
    }
    cfg.validate()?;
    let image = io::read_image(&a.input)?;
    let (psf, _) = psf_source::load(&cfg.psf)?;
    let camera = Camera::new(&cfg, psf)?;
    let out = camera.apply(&image, a.seed)?;
    let depth = match cfg.bit_depth {
        16 => BitDepth::Sixteen,
        8 => BitDepth::Eight,
        other => bail!("--bit-depth must be 8 or 16, got {other}"),
    };
    io::write_image(&a.out, &out, depth)?;
    println!(
        "{} → {} ({}x{}x{}); stages: {}",
        a.input.display(),
        a.out.display(),
        out.channels(),
        out.height(),
        out.width(),
        camera.stage_names().join(" → ")
    );
    Ok(())
}

fn psf(a: PsfArgs) -> Result<()> {
    use pins::optics::{Lens, Profile, PsfParams, compute_psf};
    let lens = Lens {
        diameter_mm: a.diameter,
        focal_mm: a.focal,
        pixel_um: a.pixel,
        design_wavelength_nm: a.design_wavelength,
        profile: match a.profile {
            ProfileArg::Hyperbolic => Profile::Hyperbolic,
            ProfileArg::Quadratic => Profile::Quadratic,
        },
        tilt_deg: a.tilt,
    };
    let params = PsfParams {
        lens,
        field_angle_deg: a.field_angle,
        kernel_size: a.size,
        grid: a.grid,
        ..PsfParams::default()
    };
    let ext = a
        .out
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    if !matches!(ext.as_str(), "exr" | "npy" | "png") {
        bail!(
            "--out {}: the PSF is written as .exr, .npy or .png",
            a.out.display()
        );
    }
    let started = std::time::Instant::now();
    let result = compute_psf(&params)?;
    let img = result.psf.image();
    if ext == "png" {
        // A PNG cannot hold the tiny normalised values; scale each channel to its peak.
        let mut shown = img.clone();
        for c in 0..shown.channels() {
            let peak = shown
                .plane(c)
                .iter()
                .cloned()
                .fold(0.0f32, f32::max)
                .max(f32::MIN_POSITIVE);
            shown.plane_mut(c).iter_mut().for_each(|v| *v /= peak);
        }
        io::write_image(&a.out, &shown, BitDepth::Sixteen)?;
    } else {
        io::write_image(&a.out, img, BitDepth::Sixteen)?;
    }
    println!(
        "{}: {}x{}x{} PSF ({:?} profile, design {} nm, field {}°, tilt {}°) in {:.1} s",
        a.out.display(),
        img.channels(),
        img.height(),
        img.width(),
        params.lens.profile,
        a.design_wavelength,
        a.field_angle,
        a.tilt,
        started.elapsed().as_secs_f64()
    );
    println!(
        "spot radius at {} nm (83.8 % encircled energy): {:.3} µm; Airy radius 1.22·λ·f/D: {:.3} µm; ratio {:.2}",
        a.design_wavelength,
        result.spot_radius_um,
        result.airy_radius_um,
        result.spot_radius_um / result.airy_radius_um
    );
    if let Some(s) = result.strehl_like {
        println!("Strehl-like peak ratio: {s:.3}");
    }
    Ok(())
}

fn bench(a: BenchArgs) -> Result<()> {
    use pins::report::bench::{BenchOptions, run};
    if a.threads.contains(&0) || a.reps == 0 {
        bail!("--threads and --reps must be positive");
    }
    let opts = BenchOptions {
        reps: a.reps,
        threads: a.threads,
        psf_sizes: a.psf_sizes,
        ..BenchOptions::default()
    };
    let report = run(&opts)?;
    print!("{}", report.markdown());
    if let Some(p) = a.json {
        let text = serde_json::to_string_pretty(&report)?;
        io::write_bytes_atomic(&p, text.as_bytes())?;
    }
    Ok(())
}

fn train(a: TrainArgs) -> Result<()> {
    use pins::flow::train::{TrainConfig, TrainOptions};
    let config = match &a.config {
        Some(p) => TrainConfig::from_file(p)?,
        None => TrainConfig::default(),
    };
    let model = config.model_config()?;
    let params = pins::flow::weights::parameter_count(&pins::flow::model::Mms::new(
        &model,
        &burn::prelude::Device::flex(),
    ));
    println!(
        "training {} ({params} parameters) on {}",
        model.name,
        a.data.display()
    );
    let opts = TrainOptions {
        data: a.data,
        out: a.out.clone(),
        resume: a.resume,
        steps: a.steps,
        stop_after: a.stop_after,
        init: a.init,
        device: pins::flow::device::select(&a.device)?,
        progress: !a.quiet && std::io::stderr().is_terminal(),
    };
    let s = pins::flow::train::train(config, &opts)?;
    println!(
        "{}: {} steps, last loss {:.4}, best validation EPE {}, {:.0} s of training",
        a.out.display(),
        s.steps,
        s.last_loss,
        s.best_val_epe
            .map(|v| format!("{v:.3}"))
            .unwrap_or_else(|| "–".into()),
        s.train_seconds
    );
    Ok(())
}

fn export(a: ExportArgs) -> Result<()> {
    let src = pins::flow::train::trainer::run_weights(&a.run)?;
    let device = burn::prelude::Device::flex();
    let (model, config) = pins::flow::weights::load(&src, &device)?;
    pins::flow::weights::save(&a.out, &model, &config)?;
    println!(
        "{} → {} ({}, {} parameters)",
        src.display(),
        a.out.display(),
        config.name,
        pins::flow::weights::parameter_count(&model)
    );
    Ok(())
}

fn infer(a: InferArgs) -> Result<()> {
    use pins::flow::{infer::Predictor, viz::flow_to_image};
    let pairs: Vec<(PathBuf, PathBuf, PathBuf, Option<PathBuf>)> =
        match (&a.frames, &a.img1, &a.img2) {
            (Some(dir), None, None) => {
                let mut frames: Vec<PathBuf> = std::fs::read_dir(dir)
                    .with_context(|| format!("reading {}", dir.display()))?
                    .filter_map(|e| e.ok().map(|e| e.path()))
                    .filter(|p| {
                        p.extension().and_then(|e| e.to_str()).is_some_and(|e| {
                            matches!(
                                e.to_ascii_lowercase().as_str(),
                                "png" | "jpg" | "jpeg" | "ppm" | "pgm" | "tif" | "tiff" | "exr"
                            )
                        })
                    })
                    .collect();
                frames.sort();
                if frames.len() < 2 {
                    bail!(
                        "--frames {}: need at least two images, found {}",
                        dir.display(),
                        frames.len()
                    );
                }
                frames
                    .windows(2)
                    .map(|w| {
                        let stem = w[0]
                            .file_stem()
                            .map(|s| s.to_string_lossy().into_owned())
                            .unwrap_or_default();
                        (
                            w[0].clone(),
                            w[1].clone(),
                            a.out.join(format!("{stem}.flo")),
                            a.viz.as_ref().map(|v| v.join(format!("{stem}.png"))),
                        )
                    })
                    .collect()
            }
            (None, Some(i1), Some(i2)) => {
                vec![(i1.clone(), i2.clone(), a.out.clone(), a.viz.clone())]
            }
            _ => bail!("give either --img1 and --img2, or --frames DIR"),
        };
    let predictor = Predictor::load_on(&a.weights, pins::flow::device::select(&a.device)?)?;
    let iters = a.iters.unwrap_or(predictor.config.iters);
    for (i1, i2, out, viz) in pairs {
        let (x, y) = io::read_image_pair(&i1, &i2)?;
        let started = std::time::Instant::now();
        let flow = predictor.predict(&x, &y, iters)?;
        let ms = started.elapsed().as_secs_f64() * 1e3;
        io::write_flow(&out, &flow)?;
        if let Some(v) = viz {
            io::write_image(&v, &flow_to_image(&flow, None), BitDepth::Eight)?;
        }
        println!(
            "{} → {}: {}x{}, max |flow| {:.2} px, {iters} iterations, {ms:.0} ms",
            i1.display(),
            out.display(),
            flow.width(),
            flow.height(),
            flow.max_magnitude()
        );
    }
    Ok(())
}

fn eval(a: EvalArgs) -> Result<()> {
    use pins::flow::{data::FlowDataset, eval::evaluate, infer::Predictor};
    if a.iters.iter().any(|&n| n == 0 || n > 256) {
        bail!("--iters values must be 1..=256");
    }
    let data = FlowDataset::open(&a.data)?;
    let predictor = Predictor::load_on(&a.weights, pins::flow::device::select(&a.device)?)?;
    let report = evaluate(
        &predictor.model,
        &predictor.config,
        &data,
        &a.iters,
        &predictor.device,
    )?;
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

fn bench_flow(a: BenchFlowArgs) -> Result<()> {
    if a.reps == 0 || a.iters == 0 {
        bail!("--reps and --iters must be positive");
    }
    let row = pins::report::flow_bench::run(&a.model, &a.mode, a.height, a.width, a.iters, a.reps)?;
    println!("{}", serde_json::to_string(&row)?);
    Ok(())
}

fn compare(a: CompareArgs) -> Result<()> {
    let (x, y) = io::read_image_pair(&a.a, &a.b)?;
    let s = pins::imaging::similarity::compare(&x, &y)?;
    if a.json {
        println!("{}", serde_json::to_string(&s)?);
    } else {
        println!("SSIM {:.6}  MAE {:.6}  MSE {:.6}", s.ssim, s.mae, s.mse);
    }
    Ok(())
}

fn optics(c: OpticsCommand) -> Result<()> {
    use pins::optics::{Lens, Profile, dof::DofParams, fov, resolution::resolution, stereo};
    match c {
        OpticsCommand::Dof {
            offsets_um,
            focal_mm,
            diameter_mm,
            pixel_um,
            coc_pixels,
            json,
        } => {
            let p = DofParams {
                focal_mm,
                diameter_mm,
                pixel_um,
                coc_pixels,
            };
            let rows = offsets_um
                .iter()
                .map(|&o| p.range(o))
                .collect::<pins::Result<Vec<_>>>()?;
            if json {
                println!("{}", serde_json::json!({ "rows": rows }));
            } else {
                println!(
                    "Δv_max = c·F/# = {:.2} µm\n\n| v0 − f (µm) | u_near (m) | u_far (m) |\n|---|---|---|",
                    p.max_shift_m() * 1e6
                );
                for r in rows {
                    let far = r
                        .u_far_m
                        .map(|v| format!("{v:.2}"))
                        .unwrap_or_else(|| "∞".into());
                    println!("| {} | {:.2} | {} |", r.v0_minus_f_um, r.u_near_m, far);
                }
            }
        }
        OpticsCommand::Resolution {
            distance_m,
            pixel_um,
            focal_mm,
            min_shift_px,
            min_target_px,
            json,
        } => {
            let r = resolution(pixel_um, focal_mm, distance_m, min_shift_px, min_target_px)?;
            if json {
                println!("{}", serde_json::to_string(&r)?);
            } else {
                println!(
                    "one pixel: {:.3} mrad ({:.4}°), {:.2} cm at {} m\nsmallest displacement ({min_shift_px} px): {:.2} cm\nsmallest object ({min_target_px} px): {:.2} cm",
                    r.pixel_angle_mrad,
                    r.pixel_angle_deg,
                    r.pixel_footprint_m * 100.0,
                    r.distance_m,
                    r.min_displacement_m * 100.0,
                    r.min_object_m * 100.0
                );
            }
        }
        OpticsCommand::Stereo {
            x1_mm,
            x2_mm,
            baseline_m,
            focal_mm,
            profile,
            json,
        } => {
            let p = match profile {
                ProfileArg::Hyperbolic => Profile::Hyperbolic,
                ProfileArg::Quadratic => Profile::Quadratic,
            };
            let z = stereo::depth(p, x1_mm, x2_mm, focal_mm, baseline_m)?;
            let (a, b) = (
                stereo::incident_angle(p, x1_mm, focal_mm)?,
                stereo::incident_angle(p, x2_mm, focal_mm)?,
            );
            if json {
                println!(
                    "{}",
                    serde_json::json!({"depth_m": z, "alpha_deg": a.to_degrees(), "beta_deg": b.to_degrees()})
                );
            } else {
                println!(
                    "α = {:.4}°, β = {:.4}°, depth Z = {z:.4} m",
                    a.to_degrees(),
                    b.to_degrees()
                );
            }
        }
        OpticsCommand::Fov {
            tilts_deg,
            fov_deg,
            spots,
            grid,
            json,
        } => {
            let cov = fov::coverage(&tilts_deg, fov_deg)?;
            let mut sweeps = Vec::new();
            if spots {
                for design in [45.0, 80.0] {
                    sweeps.push((design, fov::spot_sweep(&Lens::default(), design, 4, grid)?));
                }
            }
            if json {
                let s: Vec<_> = sweeps
                    .iter()
                    .map(|(d, r)| serde_json::json!({"designed_fov_deg": d, "rows": r}))
                    .collect();
                println!("{}", serde_json::json!({"coverage": cov, "spots": s}));
            } else {
                for (i, s) in cov.sectors.iter().enumerate() {
                    println!("lens {}: {:.1}° … {:.1}°", i + 1, s[0], s[1]);
                }
                println!(
                    "total field of view {:.1}°; neighbour overlaps {:?}°",
                    cov.total_deg, cov.overlaps_deg
                );
                for (design, rows) in sweeps {
                    println!(
                        "\nlens designed for {design}° (hyperbolic, 532 nm): spot radius / Airy radius"
                    );
                    for r in rows {
                        println!(
                            "  {:5.1}°: {:8.2} µm / {:.2} µm = {:.1}",
                            r.field_angle_deg,
                            r.spot_radius_um,
                            r.airy_radius_um,
                            r.spot_radius_um / r.airy_radius_um
                        );
                    }
                }
            }
        }
    }
    Ok(())
}

fn array(c: ArrayCommand) -> Result<()> {
    use pins::wide::{ArrayLayout, Calibration, Stitcher, calibrate, render};
    let layout_of = |p: &Option<PathBuf>| -> Result<ArrayLayout> {
        let l = match p {
            Some(p) => serde_json::from_str::<ArrayLayout>(
                &std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?,
            )
            .with_context(|| format!("array layout {}", p.display()))?,
            None => ArrayLayout::default(),
        };
        render::check_layout(&l)?;
        Ok(l)
    };
    match c {
        ArrayCommand::Render {
            input,
            grid,
            dots,
            out,
            config,
            camera,
            seed,
        } => {
            let layout = layout_of(&config)?;
            let scene = match (input, grid) {
                (Some(p), false) => io::read_image(&p)?,
                (None, true) => render::dot_grid_target(&layout, dots)?.0,
                _ => bail!("give either --in WIDE.png or --grid"),
            };
            let mut raw = render::render_raw(&layout, &scene)?;
            match camera.as_str() {
                "none" => {}
                "default" => {
                    let cfg = CameraConfig::default();
                    let (psf, _) = psf_source::load(&cfg.psf)?;
                    raw = Camera::new(&cfg, psf)?.apply(&raw, seed)?;
                }
                other => bail!("--camera {other:?}: use default or none"),
            }
            io::write_image(&out, &raw, BitDepth::Eight)?;
            println!(
                "{}: {}x{} raw frame of {} lenses",
                out.display(),
                raw.width(),
                raw.height(),
                layout.lenses.len()
            );
        }
        ArrayCommand::Calibrate {
            grid,
            out,
            config,
            dots,
            order,
        } => {
            let layout = layout_of(&config)?;
            if let Some(o) = order
                && !(2..=6).contains(&o)
            {
                bail!("--order must be 2..=6, got {o}");
            }
            let raw = io::read_image(&grid)?;
            let calib = calibrate(&layout, &raw, dots, order)?;
            io::write_bytes_atomic(&out, serde_json::to_string_pretty(&calib)?.as_bytes())?;
            println!(
                "| lens | dots | order | RMS (px) | max (px) | held-out RMS by order |\n|---|---|---|---|---|---|"
            );
            for (i, l) in calib.lenses.iter().enumerate() {
                let ho: Vec<String> = l
                    .held_out
                    .iter()
                    .map(|(o, r)| format!("{o}: {r:.3}"))
                    .collect();
                println!(
                    "| {} | {} | {} | {:.3} | {:.3} | {} |",
                    i + 1,
                    l.dots,
                    l.fx.order,
                    l.rms_px,
                    l.max_px,
                    ho.join(", ")
                );
            }
        }
        ArrayCommand::Bench {
            grid,
            config,
            dots,
            reps,
        } => {
            let layout = layout_of(&config)?;
            let raw = io::read_image(&grid)?;
            let rows = pins::wide::bench::orders_table(&layout, &raw, dots, reps.max(1))?;
            println!(
                "| order | RMS (px) | max (px) | held-out RMS (px) | stitch ms (1 core) | frames/s |\n|---|---|---|---|---|---|"
            );
            for r in rows {
                println!(
                    "| {} | {:.3} | {:.3} | {:.3} | {:.1} | {:.0} |",
                    r.order, r.rms_px, r.max_px, r.held_out_rms_px, r.stitch_ms, r.frames_per_s
                );
            }
        }
        ArrayCommand::Stitch { calib, input, out } => {
            let text = std::fs::read_to_string(&calib)
                .with_context(|| format!("reading {}", calib.display()))?;
            let calib: Calibration = serde_json::from_str(&text)
                .with_context(|| format!("calibration {}", calib.display()))?;
            let stitcher = Stitcher::new(&calib)?;
            let jobs: Vec<(PathBuf, PathBuf)> = if input.is_dir() {
                let mut v: Vec<PathBuf> = std::fs::read_dir(&input)?
                    .filter_map(|e| e.ok().map(|e| e.path()))
                    .filter(|p| p.is_file())
                    .collect();
                v.sort();
                v.into_iter()
                    .map(|p| {
                        (
                            p.clone(),
                            out.join(p.file_name().unwrap_or_default())
                                .with_extension("png"),
                        )
                    })
                    .collect()
            } else {
                vec![(input, out)]
            };
            for (src, dst) in jobs {
                let raw = io::read_image(&src)?;
                let started = std::time::Instant::now();
                let wide = stitcher.apply(&raw)?;
                let ms = started.elapsed().as_secs_f64() * 1e3;
                io::write_image(&dst, &wide, BitDepth::Eight)?;
                println!(
                    "{} → {} ({}x{}) in {ms:.1} ms",
                    src.display(),
                    dst.display(),
                    wide.width(),
                    wide.height()
                );
            }
        }
    }
    Ok(())
}

fn track(a: TrackArgs) -> Result<()> {
    use pins::track::{mtp::MtpConfig, multi::TrackerConfig, run};
    let tracker = TrackerConfig {
        mtp: MtpConfig {
            window: a.window,
            order: a.order,
            ..MtpConfig::default()
        },
        ..TrackerConfig::default()
    };
    let opts = run::TrackOptions {
        tracker,
        horizons: a.horizons,
        threshold: a.threshold,
        min_area: a.min_area,
    };
    let files = run::flow_files(&a.flows)?;
    let started = std::time::Instant::now();
    let tracks = run::track_flows(&files, &opts)?;
    let ms = started.elapsed().as_secs_f64() * 1e3 / files.len() as f64;
    let out = a.out.join("tracks.json");
    io::write_bytes_atomic(&out, serde_json::to_string_pretty(&tracks)?.as_bytes())?;
    println!(
        "{}: {} objects over {} frames, {ms:.1} ms per frame",
        out.display(),
        tracks.objects.len(),
        files.len()
    );
    Ok(())
}
