//! The `pins` command line: parses flags, calls the library, prints. No logic of its own.

mod cli;

// Frames are large (a 3×480×1440 float frame is 8 MB); mimalloc reuses freed blocks of that size
// instead of returning them to the kernel, so a frame does not pay thousands of page faults.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};

use cli::array::{ArrayCommand, array};
use cli::calibrate::{CalibrateCommand, calibrate};
use cli::data::{
    BenchArgs, GenerateArgs, PackArgs, PsfArgs, SimulateArgs, UnpackArgs, bench, generate, pack,
    psf, simulate, unpack,
};
use cli::flow::{
    AverageArgs, BenchFlowArgs, BenchLiveArgs, BenchRealArgs, DetectLimitsArgs, EvalArgs,
    ExportArgs, InferArgs, RefineArgs, TrainArgs, average, bench_flow, bench_live, bench_real,
    detect_limits, eval, export, infer, refine, train,
};
use cli::live::{LiveArgs, live};
use cli::optics::{CompareArgs, OpticsCommand, compare, optics};
use cli::track::{TrackArgs, track};

/// Metalens motion sensing: camera simulator, flow dataset generator and optics.
#[derive(Parser)]
#[command(name = "pins", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Largest image or flow (width × height) any reader accepts; files declaring more are
    /// refused before decoding. Default: 64000000 (64 MP, sized for a 24 GB machine).
    #[arg(long, global = true, value_name = "N")]
    max_pixels: Option<u64>,
}

#[derive(Subcommand)]
enum Command {
    /// Generate image pairs with exact ground-truth flow through the metalens camera.
    Generate(GenerateArgs),
    /// Pack a dataset into WebDataset tar shards with an index (train and eval read them directly).
    Pack(PackArgs),
    /// Unpack WebDataset shards written by `pins pack` back into a dataset folder.
    Unpack(UnpackArgs),
    /// Apply the metalens camera model to one image.
    Simulate(SimulateArgs),
    /// Fit the camera model to a real camera from its captures: noise by photon transfer, the
    /// PSF from a point source.
    #[command(subcommand)]
    Calibrate(CalibrateCommand),
    /// Compute a metalens PSF by scalar diffraction and compare its spot with the Airy radius.
    Psf(PsfArgs),
    /// Benchmark the camera model: throughput, and direct vs FFT convolution against f64.
    Bench(BenchArgs),
    /// Train the MMS flow network on a dataset from `pins generate`.
    Train(TrainArgs),
    /// Export a training run's weights (safetensors with the model config inside).
    Export(ExportArgs),
    /// Average several weights files of one network, tensor by tensor (snapshots of a training run: stochastic weight averaging)
    Average(AverageArgs),
    /// Estimate optical flow with trained weights, for one pair or a folder of frames.
    Infer(InferArgs),
    /// Evaluate weights on a dataset: EPE, AE, 1/3/5 px and ms per pair for several iteration counts.
    Eval(EvalArgs),
    /// Refine a given flow (any method's, or ground truth) by the variational refinement that
    /// follows the network in the flow commands.
    Refine(RefineArgs),
    /// Time MMS inference or one training step (random weights), or the variational
    /// refinement alone, and print a JSON line.
    BenchFlow(BenchFlowArgs),
    /// Benchmark MMS, OpenCV DIS/Farneback and zero flow on real pairs, clean and through the
    /// camera: per-set and per-pair EPE, 1/3/5 px, ms per pair, and EPE-against-time plots.
    BenchReal(BenchRealArgs),
    /// The live system's error against run time on rendered clips: flow EPE against ms per pair and tracking one frame ahead against the frames per second it keeps up with, for operating points (size, iterations, reuse, warm start, refinement) and DIS's presets
    BenchLive(BenchLiveArgs),
    /// Note S12's detection limits through the network (Fig. S10 a-g): flow magnitude and
    /// direction error on the moving region, share detected, false-motion area.
    DetectLimits(DetectLimitsArgs),
    /// SSIM, MAE and MSE of two images (Note S7).
    Compare(CompareArgs),
    /// Optics calculators: depth of field, detection limits, stereo depth, field of view.
    #[command(subcommand)]
    Optics(OpticsCommand),
    /// The wide-angle 3-lens array: raw frames, calibration, stitching (Note S3).
    #[command(subcommand)]
    Array(ArrayCommand),
    /// Track moving objects through a folder of flow maps and predict their trajectories (Note S13).
    Track(Box<TrackArgs>),
    /// Read the ESP32 camera's MJPEG stream (or a recording), estimate flow, track and predict
    /// live: one JSON line per processed frame, --record/--replay, a browser view (Note S1).
    Live(LiveArgs),
}

/// mimalloc's `mi_option_purge_delay` (the 16th entry of `mi_option_e` in mimalloc.h, v2 and v3):
/// how many milliseconds freed memory stays committed before it is returned to the kernel.
const MI_OPTION_PURGE_DELAY: libmimalloc_sys::mi_option_t = 15;

fn main() {
    // The flow network frees and reallocates tensors of the same sizes every iteration; each
    // block handed back to the kernel comes back as fresh zeroed pages (about 8000 page faults
    // per 368×496 inference). Keeping freed memory committed (−1: never purge) removes them at
    // the cost of a higher peak (mms-small at 368×496: 264 MB instead of 110 MB).
    // SAFETY: sets a process-wide mimalloc option before any thread is started.
    if std::env::var_os("MIMALLOC_PURGE_DELAY").is_none() {
        unsafe { libmimalloc_sys::mi_option_set(MI_OPTION_PURGE_DELAY, -1) };
    }
    let cli = parse_cli();
    if let Some(n) = cli.max_pixels {
        pins::io::budget::set_max_pixels(n);
    }
    // The command runs on a worker thread of rayon's pool. Each parallel kernel it calls (a
    // convolution, a lookup) then splits its work among the workers directly; called from outside
    // the pool, every call would be handed over to the pool and the calling thread parked until it
    // ends: a training step of mms-small measured 368 ms and 83 k context switches per 13 steps
    // that way, against 297 ms and 11 k on a worker.
    let result = rayon::scope(|_| run(cli.command));
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

/// Parses the command line. Every option that takes a value accepts a negative number
/// (`--gamma -1`), so that the value reaches validation and gets its own message instead of
/// clap's "unexpected argument".
fn parse_cli() -> Cli {
    fn negatives(cmd: clap::Command) -> clap::Command {
        cmd.mut_args(|a| {
            if a.get_action().takes_values() {
                a.allow_negative_numbers(true)
            } else {
                a
            }
        })
        .mut_subcommands(negatives)
    }
    let matches = negatives(Cli::command()).get_matches();
    Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit())
}

fn run(command: Command) -> anyhow::Result<()> {
    match command {
        Command::Generate(a) => generate(a),
        Command::Pack(a) => pack(a),
        Command::Unpack(a) => unpack(a),
        Command::Simulate(a) => simulate(a),
        Command::Calibrate(c) => calibrate(c),
        Command::Psf(a) => psf(a),
        Command::Bench(a) => bench(a),
        Command::Train(a) => train(a),
        Command::Export(a) => export(a),
        Command::Average(a) => average(a),
        Command::Infer(a) => infer(a),
        Command::Eval(a) => eval(a),
        Command::Refine(a) => refine(a),
        Command::BenchFlow(a) => bench_flow(a),
        Command::BenchReal(a) => bench_real(a),
        Command::BenchLive(a) => bench_live(a),
        Command::DetectLimits(a) => detect_limits(a),
        Command::Compare(a) => compare(a),
        Command::Optics(c) => optics(c),
        Command::Array(c) => array(c),
        Command::Track(a) => track(*a),
        Command::Live(a) => live(a),
    }
}
