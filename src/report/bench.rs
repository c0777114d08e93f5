//! `pins bench`: error against run time for the camera model — pipeline throughput at two frame
//! sizes on one and two threads, and direct against FFT convolution over PSF sizes, each with
//! its error against a float64 reference.

use serde::Serialize;

pub use super::timing::median_ms;
use crate::error::{Error, Result};
use crate::imaging::convolve::{FftConvolver, convolve_direct, convolve_reference};
use crate::imaging::{Camera, CameraConfig, psf_source};
use crate::optics::Psf;
use crate::scene::texture::procedural;
use crate::types::Image;

/// One pipeline measurement.
#[derive(Clone, Debug, Serialize)]
pub struct PipelineRow {
    pub height: usize,
    pub width: usize,
    pub threads: usize,
    /// Median milliseconds to image one 3-channel frame.
    pub ms_per_frame: f64,
    /// Pairs (two frames) per second.
    pub pairs_per_s: f64,
    /// Median milliseconds of each stage, in pipeline order.
    pub stages_ms: Vec<(String, f64)>,
}

/// One convolution measurement.
#[derive(Clone, Debug, Serialize)]
pub struct ConvRow {
    pub psf_size: usize,
    pub direct_ms: Option<f64>,
    pub fft_ms: f64,
    /// Largest absolute difference to the f64 reference, on [0, 1] data.
    pub direct_max_err: Option<f64>,
    pub fft_max_err: f64,
    /// What `ConvMethod::Auto` picks for this size.
    pub auto_choice: String,
}

/// The whole report.
#[derive(Clone, Debug, Serialize)]
pub struct BenchReport {
    pub pipeline: Vec<PipelineRow>,
    pub convolution_plane: [usize; 2],
    pub convolution: Vec<ConvRow>,
}

/// What to measure.
#[derive(Clone, Debug)]
pub struct BenchOptions {
    pub sizes: Vec<(usize, usize)>,
    pub threads: Vec<usize>,
    pub psf_sizes: Vec<usize>,
    /// Plane for the convolution table `[H, W]`.
    pub conv_plane: (usize, usize),
    pub reps: usize,
    /// Skip direct convolution above this kernel size (it grows as K²).
    pub max_direct: usize,
}

impl Default for BenchOptions {
    fn default() -> Self {
        Self {
            sizes: vec![(384, 512), (480, 1440)],
            threads: vec![1, 2],
            psf_sizes: vec![9, 17, 33, 65, 129],
            conv_plane: (384, 512),
            reps: 5,
            max_direct: 65,
        }
    }
}

/// Crops the centred `k × k` window of a PSF channel (k odd, at most the PSF's size), or pads it.
fn resize_kernel(psf: &Psf, k: usize) -> Vec<f32> {
    let (h, w) = psf.size();
    let src = psf.channel(1);
    let mut out = vec![0.0f32; k * k];
    for y in 0..k {
        for x in 0..k {
            let sy = y as isize - (k / 2) as isize + (h / 2) as isize;
            let sx = x as isize - (k / 2) as isize + (w / 2) as isize;
            if sy >= 0 && sx >= 0 && (sy as usize) < h && (sx as usize) < w {
                out[y * k + x] = src[sy as usize * w + sx as usize];
            }
        }
    }
    let s: f64 = out.iter().map(|&v| v as f64).sum();
    out.iter_mut().for_each(|v| *v = (*v as f64 / s) as f32);
    out
}

/// Runs the benchmark with the shipped default camera.
pub fn run(opts: &BenchOptions) -> Result<BenchReport> {
    let (psf, _) = psf_source::load("default")?;
    let camera = Camera::new(&CameraConfig::default(), psf.clone())?;
    let mut pipeline = Vec::new();
    for &(h, w) in &opts.sizes {
        let frame = procedural(7, 3, h, w, 200.0);
        for &threads in &opts.threads {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .map_err(|e| Error::invalid("threads", e.to_string()))?;
            let ms = pool.install(|| median_ms(opts.reps, || camera.apply(&frame, 1)));
            let mut stages_ms = Vec::new();
            let mut img = frame.clone();
            for stage in camera.stages() {
                let input = img.clone();
                let t = pool.install(|| {
                    median_ms(opts.reps, || {
                        let mut x = input.clone();
                        stage.apply(&mut x, 1)
                    })
                });
                stage.apply(&mut img, 1)?;
                stages_ms.push((stage.name().to_string(), t));
            }
            pipeline.push(PipelineRow {
                height: h,
                width: w,
                threads,
                ms_per_frame: ms,
                pairs_per_s: 1e3 / (2.0 * ms),
                stages_ms,
            });
        }
    }
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .map_err(|e| Error::invalid("threads", e.to_string()))?;
    let convolution = one.install(|| convolution_table(opts, &psf))?;
    Ok(BenchReport {
        pipeline,
        convolution_plane: [opts.conv_plane.0, opts.conv_plane.1],
        convolution,
    })
}

/// Direct against FFT on one core, with errors against the f64 reference.
fn convolution_table(opts: &BenchOptions, psf: &Psf) -> Result<Vec<ConvRow>> {
    let (ph, pw) = opts.conv_plane;
    let plane_img: Image = procedural(3, 1, ph, pw, 100.0);
    let plane = plane_img.plane(0);
    let mut convolution = Vec::new();
    for &k in &opts.psf_sizes {
        if k % 2 == 0 || k == 0 {
            return Err(Error::invalid("PSF size", format!("{k} is not odd")));
        }
        let kernel = resize_kernel(psf, k);
        let reference = convolve_reference(plane, ph, pw, &kernel, k, k);
        let err = |v: &[f32]| {
            v.iter()
                .zip(&reference)
                .map(|(&a, &b)| (a as f64 - b).abs())
                .fold(0.0, f64::max)
        };
        let (direct_ms, direct_max_err) = if k <= opts.max_direct {
            let d = convolve_direct(plane, ph, pw, &kernel, k, k);
            (
                Some(median_ms(opts.reps, || {
                    convolve_direct(plane, ph, pw, &kernel, k, k)
                })),
                Some(err(&d)),
            )
        } else {
            (None, None)
        };
        let conv = FftConvolver::new(&kernel, k, k, ph, pw);
        let f = conv.convolve(plane);
        // The kernel spectrum is computed once per camera and frame size, so it is not timed.
        let fft_ms = median_ms(opts.reps, || conv.convolve(plane));
        let auto_choice = format!(
            "{:?}",
            crate::imaging::convolve::choose_method(ph, pw, k, k)
        )
        .to_lowercase();
        convolution.push(ConvRow {
            psf_size: k,
            direct_ms,
            fft_ms,
            direct_max_err,
            fft_max_err: err(&f),
            auto_choice,
        });
    }
    Ok(convolution)
}

impl BenchReport {
    /// Markdown tables.
    pub fn markdown(&self) -> String {
        let mut s = String::from(
            "| frame (H×W×3) | threads | ms per frame | pairs/s | stages (ms, each including a copy of the frame) |\n|---|---|---|---|---|\n",
        );
        for r in &self.pipeline {
            let stages: Vec<String> = r
                .stages_ms
                .iter()
                .map(|(n, t)| format!("{n} {t:.1}"))
                .collect();
            s += &format!(
                "| {}×{} | {} | {:.1} | {:.1} | {} |\n",
                r.height,
                r.width,
                r.threads,
                r.ms_per_frame,
                r.pairs_per_s,
                stages.join(", ")
            );
        }
        s += &format!(
            "\nConvolution of one {}×{} plane on one thread (max abs error against a float64 reference, [0, 1] data):\n\n",
            self.convolution_plane[0], self.convolution_plane[1]
        );
        s += "| PSF | direct ms | direct error | FFT ms | FFT error | auto picks |\n|---|---|---|---|---|---|\n";
        for r in &self.convolution {
            let d = r
                .direct_ms
                .map(|v| format!("{v:.1}"))
                .unwrap_or_else(|| "–".into());
            let de = r
                .direct_max_err
                .map(|v| format!("{v:.1e}"))
                .unwrap_or_else(|| "–".into());
            s += &format!(
                "| {0}×{0} | {1} | {2} | {3:.1} | {4:.1e} | {5} |\n",
                r.psf_size, d, de, r.fft_ms, r.fft_max_err, r.auto_choice
            );
        }
        s
    }
}
