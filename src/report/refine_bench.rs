//! `pins bench-flow --mode refine`: the variational refinement alone, timed as a median after a
//! warm-up on a realistic pair (a procedural texture and a smoothly warped copy, 8-bit, with a
//! start flow as rough as a 1/8-resolution estimate), with its end-point error before and after;
//! optionally writes the pair so `scripts/bench_refine_compare.sh` can time OpenCV on the same.

use std::path::Path;

use serde::Serialize;

use super::flow_bench::peak_rss_mb;
use super::timing::median_ms;
use crate::error::{Error, Result};
use crate::flow::refine::{RefineConfig, refine};
use crate::flow::resample::resize_flow;
use crate::scene::texture::{procedural, sample_bilinear};
use crate::types::{Flow, Image};

/// One measurement, printed as a JSON line.
#[derive(Clone, Debug, Serialize)]
pub struct RefineBenchRow {
    pub tool: String,
    pub mode: String,
    pub height: usize,
    pub width: usize,
    pub threads: usize,
    pub scales: Vec<u32>,
    /// Median milliseconds of one `refine` call.
    pub ms: f64,
    /// Mean end-point error of the start flow and of the refined flow against the truth, over
    /// the pixels at least 8 px from the border.
    pub epe_start: f64,
    pub epe_refined: f64,
    pub peak_rss_mb: f64,
}

/// The benchmark pair: frames 1 and 2 (grey, 8-bit levels), the true flow and the start flow.
pub struct RefinePair {
    pub frame1: Image,
    pub frame2: Image,
    pub truth: Flow,
    pub start: Flow,
}

/// The backward map of the pair: frame 2 at `q` is frame 1 at `q − g(q)`; a smooth field of a
/// few pixels (a translation with a slow swirl), as a camera or a scene moves.
fn backward_map(x: f32, y: f32, h: usize, w: usize) -> (f32, f32) {
    let (tx, ty) = (
        std::f32::consts::TAU * x / w as f32,
        std::f32::consts::TAU * y / h as f32,
    );
    (
        3.0 + 2.0 * ty.sin() * (0.5 * tx).cos(),
        -1.5 + 1.5 * tx.cos() * (0.5 * ty).sin(),
    )
}

/// 8-bit quantisation, as a camera's frames are.
fn quantise(x: f32) -> f32 {
    (255.0 * x.clamp(0.0, 1.0)).round() / 255.0
}

/// The pair at `h × w` (each side at least 16).
pub fn pair(h: usize, w: usize) -> Result<RefinePair> {
    if h < 16 || w < 16 {
        return Err(Error::invalid(
            "size",
            format!("{h}x{w}: the refinement benchmark needs sides of at least 16"),
        ));
    }
    let tex = procedural(7, 1, h, w, 48.0);
    let frame1 = tex.plane(0).iter().map(|&x| quantise(x)).collect();
    let mut frame2 = vec![0.0f32; h * w];
    let mut truth = Flow::zeros(h, w);
    for y in 0..h {
        for x in 0..w {
            let (xf, yf) = (x as f32, y as f32);
            let (gu, gv) = backward_map(xf, yf, h, w);
            frame2[y * w + x] = quantise(sample_bilinear(&tex, 0, xf - gu, yf - gv));
            // The forward flow f at p solves p + f = q with q − g(q) = p, i.e. f = g(p + f):
            // a contraction (|∇g| ≈ 0.03), so a few fixed-point steps converge.
            let mut f = (gu, gv);
            for _ in 0..10 {
                f = backward_map(xf + f.0, yf + f.1, h, w);
            }
            truth.set(y, x, f.0, f.1);
        }
    }
    // The start: the truth seen at 1/8 resolution (what the network delivers) and off by a
    // smooth error of up to 0.75 px.
    let coarse = resize_flow(&truth, h.div_ceil(8), w.div_ceil(8))?;
    let mut start = resize_flow(&coarse, h, w)?;
    for y in 0..h {
        for x in 0..w {
            let (u, v) = start.get(y, x);
            let e =
                0.75 * (std::f32::consts::TAU * (x as f32 / w as f32 + y as f32 / h as f32)).sin();
            start.set(y, x, u + e, v - 0.5 * e);
        }
    }
    Ok(RefinePair {
        frame1: Image::from_vec(1, h, w, frame1)?,
        frame2: Image::from_vec(1, h, w, frame2)?,
        truth,
        start,
    })
}

/// Mean end-point error of `flow` against `truth` over the pixels at least 8 px inside.
pub fn epe(flow: &Flow, truth: &Flow) -> f64 {
    let (h, w) = (flow.height(), flow.width());
    let (mut s, mut n) = (0.0f64, 0usize);
    for y in 8..h.saturating_sub(8) {
        for x in 8..w.saturating_sub(8) {
            let ((u, v), (tu, tv)) = (flow.get(y, x), truth.get(y, x));
            s += f64::from((u - tu).hypot(v - tv));
            n += 1;
        }
    }
    s / n.max(1) as f64
}

/// Writes the pair to `dir`: `frame1.png`, `frame2.png`, `start.flo`, `truth.flo`.
pub fn write_pair(p: &RefinePair, dir: &Path) -> Result<()> {
    use crate::io::{BitDepth, write_flo, write_image};
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    write_image(&dir.join("frame1.png"), &p.frame1, BitDepth::Eight)?;
    write_image(&dir.join("frame2.png"), &p.frame2, BitDepth::Eight)?;
    write_flo(&dir.join("start.flo"), &p.start)?;
    write_flo(&dir.join("truth.flo"), &p.truth)
}

/// Times `refine` with `cfg` on the pair at `h × w` over `reps` runs; writes the pair to
/// `pair_out` when given.
pub fn run(
    h: usize,
    w: usize,
    reps: usize,
    cfg: &RefineConfig,
    pair_out: Option<&Path>,
) -> Result<RefineBenchRow> {
    let p = pair(h, w)?;
    if let Some(dir) = pair_out {
        write_pair(&p, dir)?;
    }
    let refined = refine(&p.frame1, &p.frame2, &p.start, cfg)?;
    let ms = median_ms(reps, || refine(&p.frame1, &p.frame2, &p.start, cfg));
    Ok(RefineBenchRow {
        tool: "pins refine".into(),
        mode: "refine".into(),
        height: h,
        width: w,
        threads: rayon::current_num_threads(),
        scales: cfg.scales.clone(),
        ms,
        epe_start: epe(&p.start, &p.truth),
        epe_refined: epe(&refined, &p.truth),
        peak_rss_mb: peak_rss_mb(),
    })
}
