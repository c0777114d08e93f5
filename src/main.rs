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
        println!("{}/manifest.json lists all {} samples", a.out.display(), summary.total);
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
            let text = std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?;
            serde_json::from_str::<CameraConfig>(&text).with_context(|| format!("config {}", p.display()))?
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
