//! `pins bench-flow --mode kernels`: where the MMS network's inference time goes. Every heavy
//! operation of one pair at a given size (enumerated from the config along the layers of
//! `flow::model`), timed on the host kernels with random data of its real shapes, with its
//! FLOPs per pair and GFLOP/s set against the machine's f32 matrix product rate measured in the
//! same run, and the whole forward pass beside it so that the table's sum can be checked.

use std::collections::HashMap;
use std::time::Instant;

use burn::prelude::*;
use serde::Serialize;

use super::flow_bench;
use super::timing::median_ms;
use crate::error::{Error, Result};
use crate::flow::kernels::geometry::Geometry;
use crate::flow::kernels::{conv, corr, lookup, norm, peak, shifted, unfold, upsample};
use crate::flow::model::MmsConfig;

mod ops;
pub use ops::{Kernel, Op, Part, ops};

/// Sides of the square products that measure the peak.
const PEAK_SIDES: [usize; 3] = [512, 1024, 2048];

/// One sample lasts at least this long (cheap operations are averaged over several calls).
const SAMPLE_MS: f64 = 20.0;

/// The measured rate of square products.
#[derive(Clone, Debug, Serialize)]
pub struct PeakRow {
    pub n: usize,
    pub threads: usize,
    pub ms: f64,
    pub gflops: f64,
}

/// One operation's row.
#[derive(Clone, Debug, Serialize)]
pub struct KernelRow {
    pub op: String,
    pub part: Part,
    pub shape: String,
    pub count: usize,
    pub mflop_per_pair: f64,
    pub ms_per_call: f64,
    pub ms_per_pair: f64,
    pub gflops: f64,
    pub percent_of_peak: f64,
    /// A stride-1 convolution that both host paths can run: the path not taken, ms per pair.
    pub other_path_ms_per_pair: Option<f64>,
}

/// The whole measurement.
#[derive(Clone, Debug, Serialize)]
pub struct KernelReport {
    pub model: String,
    pub height: usize,
    pub width: usize,
    pub iters: usize,
    pub threads: usize,
    pub reps: usize,
    pub peak: Vec<PeakRow>,
    /// Best rate on the kernels' threads, and on one.
    pub peak_gflops: f64,
    pub peak_gflops_one_thread: f64,
    /// The best rate on the kernels' threads measured again after the operations: how much
    /// the machine's load changed during the run.
    pub peak_gflops_after: f64,
    /// `/proc/loadavg`'s 1-minute load before and after the run (0 where unreadable).
    pub load_before: f64,
    pub load_after: f64,
    pub rows: Vec<KernelRow>,
    /// Σ ms per pair of the rows, and of each part.
    pub sum_ms: f64,
    pub part_ms: Vec<(Part, f64)>,
    /// The whole forward pass (`bench-flow --mode infer`), (updates, ms).
    pub forward_ms: Vec<(usize, f64)>,
}

/// Measures the peak, every operation of `model` at `height`×`width` with `iters` updates, and
/// the whole forward pass with 4 and 12 updates.
pub fn run(
    model: &str,
    height: usize,
    width: usize,
    iters: usize,
    reps: usize,
    device: &Device,
) -> Result<KernelReport> {
    let cfg = MmsConfig::named(model)?;
    if iters == 0 || reps == 0 {
        return Err(Error::invalid(
            "bench-flow --mode kernels",
            "--iters and --reps must be positive",
        ));
    }
    let threads = rayon::current_num_threads();
    let load_before = load();
    let mut peak = Vec::new();
    for n in PEAK_SIDES {
        for t in [threads, 1] {
            let ms = peak_ms(n, t, reps);
            peak.push(PeakRow {
                n,
                threads: t,
                ms,
                gflops: 2.0 * (n as f64).powi(3) / (ms * 1e6),
            });
        }
    }
    let best = |t: usize| {
        peak.iter()
            .filter(|p| p.threads == t)
            .map(|p| p.gflops)
            .fold(0.0, f64::max)
    };
    let (peak_gflops, peak_gflops_one_thread) = (best(threads), best(1));
    // The forward pass checks the size and runs first, so that a bad size fails early.
    let mut forward_ms = Vec::new();
    for n in [4, 12] {
        let row = flow_bench::run(model, "infer", height, width, n, reps, device)?;
        forward_ms.push((n, row.ms));
    }
    let mut rows = Vec::new();
    for (i, op) in ops(&cfg, height, width, iters).into_iter().enumerate() {
        let ms = time(prepare(&op.kernel, i as u64), reps);
        let other = other_path(&op.kernel, i as u64).map(|call| time(call, reps));
        let mflop = op.kernel.flops() * op.count as f64 / 1e6;
        let ms_pair = ms * op.count as f64;
        let gflops = mflop / ms_pair;
        rows.push(KernelRow {
            op: op.name,
            part: op.part,
            shape: op.kernel.shape(),
            count: op.count,
            mflop_per_pair: mflop,
            ms_per_call: ms,
            ms_per_pair: ms_pair,
            gflops,
            percent_of_peak: 100.0 * gflops / peak_gflops,
            other_path_ms_per_pair: other.map(|ms| ms * op.count as f64),
        });
    }
    let peak_gflops_after = PEAK_SIDES
        .iter()
        .map(|&n| 2.0 * (n as f64).powi(3) / (peak_ms(n, threads, reps) * 1e6))
        .fold(0.0, f64::max);
    let part_ms = [Part::Encoders, Part::Pair, Part::Update]
        .map(|p| {
            (
                p,
                rows.iter()
                    .filter(|r| r.part == p)
                    .map(|r| r.ms_per_pair)
                    .sum(),
            )
        })
        .to_vec();
    Ok(KernelReport {
        model: model.into(),
        height,
        width,
        iters,
        threads,
        reps,
        peak,
        peak_gflops,
        peak_gflops_one_thread,
        peak_gflops_after,
        load_before,
        load_after: load(),
        sum_ms: rows.iter().map(|r| r.ms_per_pair).sum(),
        rows,
        part_ms,
        forward_ms,
    })
}

/// The 1-minute load average, 0 where `/proc/loadavg` cannot be read.
fn load() -> f64 {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse().ok())
        .unwrap_or(0.0)
}

/// Best time of `reps` square products of side `n` on `threads` threads, after one warm-up.
fn peak_ms(n: usize, threads: usize, reps: usize) -> f64 {
    let (a, b) = (noise(n * n, 1), noise(n * n, 2));
    let mut c = vec![0f32; n * n];
    peak::square_product(&a, &b, &mut c, n, threads);
    (0..reps)
        .map(|_| {
            let s = Instant::now();
            peak::square_product(&a, &b, &mut c, n, threads);
            std::hint::black_box(&c);
            s.elapsed().as_secs_f64() * 1e3
        })
        .fold(f64::INFINITY, f64::min)
}

/// Median ms of one `call`: each of `reps` samples the mean of enough calls to last
/// [`SAMPLE_MS`].
fn time(mut call: Box<dyn FnMut()>, reps: usize) -> f64 {
    let s = Instant::now();
    call();
    let once = s.elapsed().as_secs_f64() * 1e3;
    let calls = ((SAMPLE_MS / once.max(1e-3)).ceil() as usize).clamp(1, 1000);
    median_ms(reps, || {
        for _ in 0..calls {
            call();
        }
    }) / calls as f64
}

/// A closure that runs `kernel` once on random inputs made here.
fn prepare(kernel: &Kernel, seed: u64) -> Box<dyn FnMut()> {
    match kernel.clone() {
        Kernel::Conv {
            xs,
            ws,
            params,
            act,
        } => {
            let x = noise(xs.iter().product(), seed);
            let w = noise(ws.iter().product(), seed + 1);
            let scale = 1.0 / ((ws[1] * ws[2] * ws[3]) as f32).sqrt();
            let w: Vec<f32> = w.iter().map(|v| v * scale).collect();
            let bias = noise(ws[0], seed + 2);
            Box::new(move || {
                let (mut y, _) = conv::conv2d(&x, xs, &w, ws, Some(&bias), &params);
                act.apply(&mut y);
                std::hint::black_box(y);
            })
        }
        Kernel::Norm { shape, groups } => {
            let x = noise(shape.iter().product(), seed);
            let (g, b) = (vec![1f32; shape[1]], vec![0f32; shape[1]]);
            Box::new(move || {
                std::hint::black_box(norm::normalise(&x, shape, groups, 1e-5, Some((&g, &b))));
            })
        }
        Kernel::Corr { shape, levels } => {
            let (f1, f2) = (
                noise(shape.iter().product(), seed),
                noise(shape.iter().product(), seed + 1),
            );
            Box::new(move || {
                std::hint::black_box(corr::pyramid(&f1, &f2, shape, levels));
            })
        }
        Kernel::Lookup {
            shape: [b, h, w],
            levels,
            radius,
        } => {
            let c = 16;
            let (pyramid, sizes) = corr::pyramid(
                &noise(b * c * h * w, seed),
                &noise(b * c * h * w, seed + 1),
                [b, c, h, w],
                levels,
            );
            // Every pixel's position plus a flow of up to ±4 cells.
            let jitter = noise(b * 2 * h * w, seed + 2);
            let coords: Vec<f32> = (0..b * 2 * h * w)
                .map(|i| {
                    let (d, p) = ((i / (h * w)) % 2, i % (h * w));
                    let at = if d == 0 { p % w } else { p / w };
                    at as f32 + 4.0 * jitter[i]
                })
                .collect();
            Box::new(move || {
                let refs: Vec<&[f32]> = pyramid.iter().map(Vec::as_slice).collect();
                std::hint::black_box(lookup::lookup_levels(
                    &refs,
                    &sizes,
                    &coords,
                    [b, h, w],
                    radius,
                ));
            })
        }
        Kernel::Upsample { shape: [b, h, w] } => {
            let flow = noise(b * 2 * h * w, seed);
            let mask: Vec<f32> = noise(b * 576 * h * w, seed + 1)
                .iter()
                .map(|v| 3.0 * v)
                .collect();
            Box::new(move || {
                std::hint::black_box(upsample::forward(&flow, &mask, [b, h, w]));
            })
        }
    }
}

/// For a convolution that both host paths can run (`shifted::eligible`), the forward pass on
/// the path [`conv::conv2d`] does not take, with the activation, on the inputs of [`prepare`].
fn other_path(kernel: &Kernel, seed: u64) -> Option<Box<dyn FnMut()>> {
    let Kernel::Conv {
        xs,
        ws,
        params,
        act,
    } = kernel.clone()
    else {
        return None;
    };
    let g = Geometry::new(xs, ws, &params);
    if !shifted::eligible(&g) {
        return None;
    }
    let x = noise(xs.iter().product(), seed);
    let w = noise(ws.iter().product(), seed + 1);
    let bias = noise(ws[0], seed + 2);
    let taken_shifted = shifted::eligible_forward(&g);
    Some(Box::new(move || {
        let mut y = if taken_shifted {
            unfold::forward(&g, &x, &w, Some(&bias))
        } else {
            shifted::forward(&g, &x, &w, Some(&bias))
        };
        act.apply(&mut y);
        std::hint::black_box(y);
    }))
}

/// `n` values in [−1, 1) from a seeded generator (the values do not change the timing).
fn noise(n: usize, seed: u64) -> Vec<f32> {
    let mut s = crate::rng::splitmix(seed ^ 0x9e37_79b9_7f4a_7c15);
    (0..n)
        .map(|_| {
            s = crate::rng::splitmix(s);
            (s >> 40) as f32 / (1u64 << 23) as f32 - 1.0
        })
        .collect()
}

impl KernelReport {
    /// The markdown table, its totals and the peak.
    pub fn markdown(&self) -> String {
        let mut s = format!(
            "{} at {}×{} (H×W), {} updates, {} threads, median of {} (peak: best of {})\n\n",
            self.model, self.height, self.width, self.iters, self.threads, self.reps, self.reps
        );
        s += "| f32 gemm n×n×n | threads | ms | GFLOP/s |\n|---|---|---|---|\n";
        for p in &self.peak {
            s += &format!(
                "| {} | {} | {:.2} | {:.1} |\n",
                p.n, p.threads, p.ms, p.gflops
            );
        }
        s += &format!(
            "\nPeak: {:.1} GFLOP/s on {} threads, {:.1} on one; {:.1} on {} threads again after \
             the operations. Load average {:.2} before, {:.2} after.\n\n",
            self.peak_gflops,
            self.threads,
            self.peak_gflops_one_thread,
            self.peak_gflops_after,
            self.threads,
            self.load_before,
            self.load_after
        );
        s += "| op | shape | count per pair | MFLOP per pair | ms per pair | GFLOP/s | % of gemm peak |\n";
        s += "|---|---|---|---|---|---|---|\n";
        for r in &self.rows {
            s += &format!(
                "| {} | {} | {} | {:.1} | {:.2} | {:.1} | {:.0} % |\n",
                r.op,
                r.shape,
                r.count,
                r.mflop_per_pair,
                r.ms_per_pair,
                r.gflops,
                r.percent_of_peak
            );
        }
        let mflop: f64 = self.rows.iter().map(|r| r.mflop_per_pair).sum();
        s += &format!(
            "| **sum** | | | {:.0} | {:.1} | {:.1} | {:.0} % |\n\n",
            mflop,
            self.sum_ms,
            mflop / self.sum_ms,
            100.0 * mflop / self.sum_ms / self.peak_gflops
        );
        s += "Stride-1 convolutions that both host paths can run, ms per pair:\n\n";
        s += "| op | shape | this path | the other path |\n|---|---|---|---|\n";
        for r in &self.rows {
            if let Some(other) = r.other_path_ms_per_pair {
                s += &format!(
                    "| {} | {} | {:.2} | {:.2} |\n",
                    r.op, r.shape, r.ms_per_pair, other
                );
            }
        }
        s += "\n";
        let parts: HashMap<&str, f64> = self
            .part_ms
            .iter()
            .map(|(p, ms)| {
                (
                    match p {
                        Part::Encoders => "encoders",
                        Part::Pair => "once per pair",
                        Part::Update => "updates",
                    },
                    *ms,
                )
            })
            .collect();
        s += &format!(
            "Sum by part: encoders {:.1} ms, updates {:.1} ms, once per pair {:.1} ms.\n",
            parts.get("encoders").copied().unwrap_or(0.0),
            parts.get("updates").copied().unwrap_or(0.0),
            parts.get("once per pair").copied().unwrap_or(0.0),
        );
        for (n, ms) in &self.forward_ms {
            s += &format!("Whole forward pass, {n} updates: {ms:.1} ms.\n");
        }
        s
    }
}
