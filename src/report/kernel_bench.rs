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
use crate::flow::kernels::act::Act;
use crate::flow::kernels::geometry::{ConvParams, Geometry};
use crate::flow::kernels::{conv, corr, lookup, norm, peak, shifted, unfold, upsample};
use crate::flow::model::{MmsConfig, NormKind};

/// Sides of the square products that measure the peak.
const PEAK_SIDES: [usize; 3] = [512, 1024, 2048];

/// One sample lasts at least this long (cheap operations are averaged over several calls).
const SAMPLE_MS: f64 = 20.0;

/// One kernel call of the network, with its real shapes.
#[derive(Clone, Debug, PartialEq)]
pub enum Kernel {
    /// `x` `[B, Cin, H, W]` ⋆ `w` `[Cout, Cin, kh, kw]` + bias, then the activation.
    Conv {
        xs: [usize; 4],
        ws: [usize; 4],
        params: ConvParams,
        act: Act,
    },
    /// Instance (groups = C) or group normalisation of `[B, C, HW]`, with γ and β.
    Norm { shape: [usize; 3], groups: usize },
    /// The correlation volume of `[B, C, H, W]` features and its pooled pyramid.
    Corr { shape: [usize; 4], levels: usize },
    /// The (2r+1)² window lookup of every level around `[B, 2, H, W]` positions.
    Lookup {
        shape: [usize; 3],
        levels: usize,
        radius: usize,
    },
    /// Convex 8× upsampling of a `[B, 2, H, W]` flow by `[B, 576, H, W]` logits.
    Upsample { shape: [usize; 3] },
}

impl Kernel {
    /// Floating-point operations of one call: 2 per multiply-add of a convolution or product,
    /// 7 per value of a normalisation (mean 1, variance 3, normalise 3), 3 per bilinear
    /// interpolation step of the lookup (rows, then columns), 81 per full-resolution pixel of
    /// the upsampling (a 9-way softmax at 5 per term, 2 × 9 multiply-adds), 4 per pooled cell.
    pub fn flops(&self) -> f64 {
        match *self {
            Kernel::Conv { xs, ws, params, .. } => {
                let g = Geometry::new(xs, ws, &params);
                2.0 * (g.batch * g.cout * g.k() * g.ho * g.wo) as f64
            }
            Kernel::Norm { shape, .. } => 7.0 * shape.iter().product::<usize>() as f64,
            Kernel::Corr {
                shape: [b, c, h, w],
                levels,
            } => {
                let hw = (h * w) as f64;
                let pooled: f64 = (1..levels)
                    .map(|l| ((h >> l) * (w >> l)) as f64)
                    .sum::<f64>();
                b as f64 * (2.0 * c as f64 * hw * hw + 4.0 * hw * pooled)
            }
            Kernel::Lookup {
                shape: [b, h, w],
                levels,
                radius,
            } => {
                let k = (2 * radius + 1) as f64;
                (b * h * w * levels) as f64 * 3.0 * ((k + 1.0) * k + k * k)
            }
            Kernel::Upsample { shape: [b, h, w] } => 81.0 * (b * 64 * h * w) as f64,
        }
    }

    /// The shapes, as the table prints them.
    pub fn shape(&self) -> String {
        match *self {
            Kernel::Conv { xs, ws, params, .. } => {
                let g = Geometry::new(xs, ws, &params);
                let path = if shifted::eligible_forward(&g) {
                    "shifted"
                } else {
                    "unfolded"
                };
                let stride = match params.stride[0] {
                    1 => String::new(),
                    s => format!("/{s}"),
                };
                let dil = match params.dilation[0] {
                    1 => String::new(),
                    d => format!(" d{d}"),
                };
                format!(
                    "{}×{}{stride}{dil} {}→{} at {}×{}, {path}",
                    ws[2], ws[3], ws[1], ws[0], g.ho, g.wo
                )
            }
            Kernel::Norm {
                shape: [_, c, hw],
                groups,
            } => format!("{c} ch × {hw} px, {groups} groups"),
            Kernel::Corr {
                shape: [_, c, h, w],
                levels,
            } => format!("{c} ch, ({h}·{w})² pairs, {levels} levels"),
            Kernel::Lookup {
                shape: [_, h, w],
                levels,
                radius,
            } => format!("{levels} × {k}² taps at {h}×{w}", k = 2 * radius + 1),
            Kernel::Upsample { shape: [_, h, w] } => format!("{h}×{w} → {}×{}", 8 * h, 8 * w),
        }
    }

    /// Weight elements of a convolution (0 for the other kernels).
    pub fn weights(&self) -> usize {
        match self {
            Kernel::Conv { ws, .. } => ws.iter().product(),
            _ => 0,
        }
    }
}

/// Where an operation runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Part {
    /// The feature encoder (both frames) and the context encoder (frame 1).
    Encoders,
    /// Once per pair: the correlation volume and the final upsampling.
    Pair,
    /// Every refinement.
    Update,
}

/// One operation of the network and how often it runs per pair.
#[derive(Clone, Debug)]
pub struct Op {
    pub name: String,
    pub part: Part,
    pub count: usize,
    pub kernel: Kernel,
}

/// The heavy operations of one pair (batch 1) at `height`×`width` with `iters` refinements,
/// each layer as often as it runs: the feature encoder on both frames (once more per frame on
/// a video that reuses them: one), the context encoder on frame 1, the update block `iters`
/// times, its flow head alone before the last update and stacked with the mask head at the
/// last (as `Mms::iterate` runs them without `all`). Identical layers are merged, their
/// counts added. Every image is timed on its own (batch 1).
pub fn ops(cfg: &MmsConfig, height: usize, width: usize, iters: usize) -> Vec<Op> {
    let mut merged: Vec<Op> = Vec::new();
    for op in layers(cfg, height, width, iters) {
        match merged
            .iter_mut()
            .find(|m| m.name == op.name && m.kernel == op.kernel)
        {
            Some(m) => m.count += op.count,
            None => merged.push(op),
        }
    }
    merged
}

/// [`ops`] before merging: one entry per layer of the model (per encoder, per head).
fn layers(cfg: &MmsConfig, height: usize, width: usize, iters: usize) -> Vec<Op> {
    let mut out = Vec::new();
    encoder(
        &mut out,
        cfg,
        cfg.feature_dim,
        cfg.feature_norm,
        2,
        [height, width],
    );
    encoder(
        &mut out,
        cfg,
        cfg.hidden_dim + cfg.context_dim,
        cfg.context_norm,
        1,
        [height, width],
    );
    let (h8, w8) = (height / 8, width / 8);
    let at = |c: usize| [1, c, h8, w8];
    let push = |out: &mut Vec<Op>, name: &str, part: Part, count: usize, kernel: Kernel| {
        if count > 0 {
            out.push(Op {
                name: name.into(),
                part,
                count,
                kernel,
            });
        }
    };
    push(
        &mut out,
        "correlation volume + pyramid",
        Part::Pair,
        1,
        Kernel::Corr {
            shape: at(cfg.feature_dim),
            levels: cfg.corr_levels,
        },
    );
    let u = Part::Update;
    push(
        &mut out,
        "correlation lookup",
        u,
        iters,
        Kernel::Lookup {
            shape: [1, h8, w8],
            levels: cfg.corr_levels,
            radius: cfg.corr_radius,
        },
    );
    let [dc, df, dout] = cfg.motion_dims;
    let conv_at = |cin: usize, cout: usize, k: usize, act: Act| {
        let p = (k - 1) / 2;
        Kernel::Conv {
            xs: at(cin),
            ws: [cout, cin, k, k],
            params: ConvParams::same(p, 1),
            act,
        }
    };
    let (relu, id) = (Act::Relu, Act::Identity);
    let motion = [
        ("motion corr 1×1", cfg.corr_channels(), dc, 1),
        ("motion corr 3×3", dc, dc, 3),
        ("motion flow 7×7", 2, df, 7),
        ("motion flow 3×3", df, df / 2, 3),
        ("motion out 3×3", dc + df / 2, dout - 2, 3),
    ];
    for (name, cin, cout, k) in motion {
        push(&mut out, name, u, iters, conv_at(cin, cout, k, relu));
    }
    // The ConvGRU at inference (`ops::gru`): x once for all three gates, h once for z and r,
    // r⊙h for q.
    let (ch, cx) = (cfg.hidden_dim, cfg.context_dim + dout);
    push(
        &mut out,
        "GRU x → z,r,q 3×3",
        u,
        iters,
        conv_at(cx, 3 * ch, 3, id),
    );
    push(
        &mut out,
        "GRU h → z,r 3×3",
        u,
        iters,
        conv_at(ch, 2 * ch, 3, id),
    );
    push(
        &mut out,
        "GRU r⊙h → q 3×3",
        u,
        iters,
        conv_at(ch, ch, 3, id),
    );
    let head = cfg.head_dim;
    push(
        &mut out,
        "flow head 3×3",
        u,
        iters - 1,
        conv_at(ch, head, 3, relu),
    );
    push(
        &mut out,
        "flow + mask heads 3×3",
        u,
        1,
        conv_at(ch, 2 * head, 3, relu),
    );
    push(&mut out, "flow out 3×3", u, iters, conv_at(head, 2, 3, id));
    push(&mut out, "mask out 1×1", u, 1, conv_at(head, 64 * 9, 1, id));
    push(
        &mut out,
        "convex upsampling",
        Part::Pair,
        1,
        Kernel::Upsample { shape: [1, h8, w8] },
    );
    out
}

/// The layers of one DSMSCE encoder (`model::encoder`) on `count` images per pair.
fn encoder(
    out: &mut Vec<Op>,
    cfg: &MmsConfig,
    dim: usize,
    norm: NormKind,
    count: usize,
    [height, width]: [usize; 2],
) {
    let [d1, d2, d3] = cfg.encoder_dims;
    let mut push = |name: &str, kernel: Kernel| {
        out.push(Op {
            name: name.into(),
            part: Part::Encoders,
            count,
            kernel,
        })
    };
    // A k×k layer with stride s and dilation d on a [1, cin, h, w] input, padded as
    // `blocks::conv` pads.
    let layer = |cin: usize, cout: usize, k: usize, s: usize, d: usize, [h, w]: [usize; 2]| {
        let p = d * (k - 1) / 2;
        Kernel::Conv {
            xs: [1, cin, h, w],
            ws: [cout, cin, k, k],
            params: ConvParams {
                stride: [s, s],
                padding: [(p, p), (p, p)],
                dilation: [d, d],
            },
            act: Act::Identity,
        }
    };
    let norm_of = |c: usize, [h, w]: [usize; 2]| {
        match norm {
            NormKind::Instance => Some(("instance norm", c)),
            NormKind::Group => Some(("group norm", 8.min(c))),
            NormKind::None => None,
        }
        .map(|(name, groups)| {
            (
                name,
                Kernel::Norm {
                    shape: [1, c, h * w],
                    groups,
                },
            )
        })
    };
    let half = |[h, w]: [usize; 2]| [h.div_ceil(2), w.div_ceil(2)];
    let s1 = [height.div_ceil(2), width.div_ceil(2)];
    push("stem 7×7/2", layer(3, d1, 7, 2, 1, [height, width]));
    let mut norms = vec![(d1, s1)];
    // The residual stages: (input, output channels, stride of the first block, input size).
    let (s2, s3) = (half(s1), half(half(s1)));
    for (stage, cin, cout, stride, size) in
        [(1, d1, d1, 1, s1), (2, d1, d2, 2, s1), (3, d2, d3, 2, s2)]
    {
        let out_size = if stride == 1 { size } else { half(size) };
        push(
            &format!("stage {stage} 3×3{}", if stride == 1 { "" } else { "/2" }),
            layer(cin, cout, 3, stride, 1, size),
        );
        for _ in 0..3 {
            push(
                &format!("stage {stage} 3×3"),
                layer(cout, cout, 3, 1, 1, out_size),
            );
        }
        norms.extend([(cout, out_size); 4]);
        if stride != 1 || cin != cout {
            push(
                &format!("stage {stage} skip 1×1/{stride}"),
                layer(cin, cout, 1, stride, 1, size),
            );
            norms.push((cout, out_size));
        }
    }
    push("pyramid fuse 3×3", layer(4 * d3, d3, 3, 1, 1, s3));
    norms.push((d3, s3));
    push("DASPP 1×1", layer(d3, d3, 1, 1, 1, s3));
    for &d in &cfg.dilations {
        push(&format!("DASPP 3×3 d{d}"), layer(d3, d3, 3, 1, d, s3));
    }
    push("DASPP global 1×1", layer(d3, d3, 1, 1, 1, [1, 1]));
    push(
        "DASPP fuse 1×1",
        layer(d3 * (cfg.dilations.len() + 2), dim, 1, 1, 1, s3),
    );
    norms.push((dim, s3));
    for (c, size) in norms {
        if let Some((name, kernel)) = norm_of(c, size) {
            push(name, kernel);
        }
    }
}

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flow::model::Mms;

    /// The enumeration walks the real model: its convolutions, one entry per layer with one
    /// update, hold exactly the model's convolution weights (the ConvGRU's split kernels and
    /// the stacked heads add up to the layers they stand for), and every one has an output.
    #[test]
    fn enumerated_layers_hold_the_models_convolution_weights() {
        struct Count(usize);
        impl burn::module::ModuleVisitor for Count {
            fn visit_float<const D: usize>(&mut self, p: &burn::module::Param<Tensor<D>>) {
                if D == 4 {
                    self.0 += p.val().dims().iter().product::<usize>();
                }
            }
        }
        for cfg in [MmsConfig::mms_small(), MmsConfig::mms()] {
            let mut c = Count(0);
            Mms::new(&cfg, &Device::flex()).visit(&mut c);
            let ops = layers(&cfg, 64, 96, 1);
            let enumerated: usize = ops.iter().map(|o| o.kernel.weights()).sum();
            assert_eq!(enumerated, c.0, "{}", cfg.name);
            for o in &ops {
                assert!(o.kernel.flops() > 0.0, "{}: {}", o.name, o.kernel.shape());
            }
        }
    }

    /// Merging keeps the counts: with 4 updates the flow head runs alone 3 times, the update
    /// block's convolutions 4 times, the encoders' on 3 images.
    #[test]
    fn counts_per_pair() {
        let ops = ops(&MmsConfig::mms_small(), 240, 320, 4);
        let count = |name: &str| {
            ops.iter()
                .filter(|o| o.name == name)
                .map(|o| o.count)
                .sum::<usize>()
        };
        assert_eq!(count("flow head 3×3"), 3);
        assert_eq!(count("flow + mask heads 3×3"), 1);
        assert_eq!(count("GRU x → z,r,q 3×3"), 4);
        assert_eq!(count("stem 7×7/2"), 3);
        assert_eq!(count("stage 1 3×3"), 12);
        assert_eq!(count("instance norm"), 2 * 17);
        assert_eq!(count("group norm"), 17);
    }
}
