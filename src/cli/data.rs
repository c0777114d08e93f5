//! Commands of the camera model and the generator: generate, simulate, psf, bench.

use std::io::IsTerminal;
use std::path::PathBuf;

use anyhow::{Context, Result, bail};

use pins::dataset::verify::ManifestCheck;
use pins::dataset::{Generator, GeneratorConfig, Shard};
use pins::imaging::{Camera, CameraConfig, psf_source};
use pins::io::{self, BitDepth};

#[derive(clap::Args)]
pub(crate) struct BenchArgs {
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
pub(crate) struct PsfArgs {
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
pub(crate) enum ProfileArg {
    Hyperbolic,
    Quadratic,
}

#[derive(clap::Args)]
pub(crate) struct GenerateArgs {
    /// Generator config (JSON); the shipped defaults when absent.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Output folder. Its config.json records the config that owns it: a run of another config
    /// is refused; runs of the same config (reruns, shards) share it, keep complete samples and
    /// redo missing or damaged ones.
    #[arg(long, default_value = "out/dataset")]
    out: PathBuf,
    /// Number of samples (overrides the config).
    #[arg(long)]
    count: Option<usize>,
    /// Master seed (overrides the config).
    #[arg(long)]
    seed: Option<u64>,
    /// Generate only shard K of N (K/N, 0-based): a contiguous block of samples. Shards may
    /// run at the same time on one folder. Without it, the shard comes from a Slurm job array
    /// (SLURM_ARRAY_TASK_ID, _MIN, _STEP, _COUNT) or a Kubernetes Indexed Job
    /// (JOB_COMPLETION_INDEX with --shards or PINS_SHARD_COUNT), else the whole dataset.
    #[arg(long)]
    shard: Option<String>,
    /// Number of shards of a scheduler's array job (Kubernetes does not export it); must agree
    /// with --shard, PINS_SHARD_COUNT and Slurm's count where those are given.
    #[arg(long)]
    shards: Option<usize>,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
    /// Check the folder given by --out without writing anything: every sample of its
    /// config.json (metadata, and each file's size and SHA-256) and manifest.json if present.
    /// Exits non-zero naming each bad sample. Without --config/--count/--seed the folder's own
    /// config is used; with them, the config they make (--config, else the folder's, with
    /// --count/--seed applied) must be the folder's, or it is an error.
    #[arg(long, conflicts_with_all = ["shard", "shards"])]
    verify: bool,
}

#[derive(clap::Args)]
pub(crate) struct PackArgs {
    /// Dataset folder (a `pins generate` folder or any layout pins reads).
    #[arg(long = "in")]
    input: PathBuf,
    /// Output folder (must not exist): shard-NNNNNN.tar, index.json, and the dataset's
    /// config.json and manifest.json when it has them.
    #[arg(long)]
    out: PathBuf,
    /// Samples per tar file.
    #[arg(long, default_value_t = 1000)]
    samples_per_shard: usize,
}

#[derive(clap::Args)]
pub(crate) struct UnpackArgs {
    /// Shard folder written by `pins pack`.
    #[arg(long = "in")]
    input: PathBuf,
    /// Output folder (must not exist), in FlyingChairs naming.
    #[arg(long)]
    out: PathBuf,
}

pub(crate) fn pack(a: PackArgs) -> Result<()> {
    let s = pins::dataset::shards::pack(&a.input, &a.out, a.samples_per_shard)?;
    println!(
        "{}: {} samples in {} shards, {:.1} MB, index.json",
        a.out.display(),
        s.samples,
        s.shards,
        s.bytes as f64 / 1e6
    );
    Ok(())
}

pub(crate) fn unpack(a: UnpackArgs) -> Result<()> {
    let n = pins::dataset::shards::unpack(&a.input, &a.out)?;
    println!("{}: {n} samples unpacked", a.out.display());
    Ok(())
}

#[derive(clap::Args)]
pub(crate) struct SimulateArgs {
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

pub(crate) fn generate(a: GenerateArgs) -> Result<()> {
    if a.verify {
        return verify_dataset(&a);
    }
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
    let source =
        pins::dataset::scheduler::resolve(a.shard.as_deref(), a.shards, |k| std::env::var(k).ok())?;
    let shard = source.shard;
    if a.shard.is_none() && shard != Shard::ALL {
        eprintln!(
            "generate: shard {}/{} from the {}",
            shard.index, shard.count, source.origin
        );
    }
    let generator = Generator::new(config)?;
    let progress = !a.quiet && std::io::stderr().is_terminal();
    let started = std::time::Instant::now();
    let summary = generator
        .run(&a.out, shard, progress)
        .with_context(|| format!("generating into {}", a.out.display()))?;
    let secs = started.elapsed().as_secs_f64();
    const LISTED: usize = 20;
    for line in summary.repairs.iter().take(LISTED) {
        println!("repaired {line}");
    }
    if summary.repairs.len() > LISTED {
        println!("… and {} more repaired", summary.repairs.len() - LISTED);
    }
    let written = summary.made + summary.repaired;
    println!(
        "{}: {} samples kept, {} made, {} repaired, in {:.1} s ({:.2} samples/s); camera stages: {}",
        a.out.display(),
        summary.kept,
        summary.made,
        summary.repaired,
        secs,
        written as f64 / secs.max(1e-9),
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

/// `generate --verify`: reads only; the error lists every bad sample.
fn verify_dataset(a: &GenerateArgs) -> Result<()> {
    let expected = if a.config.is_some() || a.count.is_some() || a.seed.is_some() {
        let mut config = match &a.config {
            Some(p) => GeneratorConfig::from_file(p)?,
            None => pins::dataset::folder::read_claim(&a.out)?,
        };
        if let Some(n) = a.count {
            config.count = n;
        }
        if let Some(s) = a.seed {
            config.seed = s;
        }
        Some(config)
    } else {
        None
    };
    let report = pins::dataset::verify(&a.out, expected.as_ref())?;
    let manifest = match &report.manifest {
        ManifestCheck::Agrees => "manifest.json agrees",
        ManifestCheck::Absent => "no manifest.json yet (written once every sample is complete)",
        ManifestCheck::Wrong(_) => "manifest.json is wrong",
    };
    let temporaries = match report.temporaries {
        0 => String::new(),
        n => format!("; {n} temporary files (of a run under way, or an interrupted one)"),
    };
    println!(
        "{}: {} of {} samples verified ({} files, {:.1} MB hashed); {manifest}{temporaries}",
        a.out.display(),
        report.good,
        report.total,
        report.files,
        report.bytes as f64 / 1e6,
    );
    if report.is_ok() {
        return Ok(());
    }
    const LISTED: usize = 100;
    let lines = report.problem_lines();
    let mut msg = format!(
        "{}: {} of {} samples are bad{}:",
        a.out.display(),
        report.problems.len(),
        report.total,
        if matches!(report.manifest, ManifestCheck::Wrong(_)) {
            " and the manifest is wrong"
        } else {
            ""
        }
    );
    for line in lines.iter().take(LISTED) {
        msg.push_str("\n  ");
        msg.push_str(line);
    }
    if lines.len() > LISTED {
        msg.push_str(&format!("\n  … and {} more", lines.len() - LISTED));
    }
    msg.push_str("\nrerun `pins generate` with the same config and --out to repair them");
    bail!(msg)
}

pub(crate) fn simulate(a: SimulateArgs) -> Result<()> {
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

pub(crate) fn psf(a: PsfArgs) -> Result<()> {
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

pub(crate) fn bench(a: BenchArgs) -> Result<()> {
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
