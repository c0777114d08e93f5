//! Evaluation: EPE, angular error and 1/3/5-px accuracy for several iteration counts, each with
//! its run time per pair, against the zero-flow baseline — error against run time (Table S4).

use std::time::Instant;

use burn::prelude::*;
use serde::{Deserialize, Serialize};

use super::data::FlowDataset;
use super::infer::{Predictor, predict_flow};
use super::metrics::{EpeBySpeed, FlowErrorSums, FlowScores};
use super::model::{Mms, MmsConfig};
use crate::error::{Error, Result};
use crate::types::{Flow, Image};

/// One row of the report: the network at `iters` iterations, alone or followed by the
/// variational refinement (`refined`; its time includes the network's).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct EvalRow {
    pub iters: usize,
    #[serde(default)]
    pub refined: bool,
    pub epe: f64,
    pub ae_deg: f64,
    pub px1: f64,
    pub px3: f64,
    pub px5: f64,
    pub ms_per_pair: f64,
    /// The EPE by ground-truth speed (Sintel's s0-10, s10-40, s40+; absent in older reports).
    #[serde(default)]
    pub by_speed: EpeBySpeed,
}

/// The method name of an MMS row: the model's name, with " + variational" for refined rows.
pub fn mms_method(model: &str, refined: bool) -> String {
    if refined {
        format!("{model} + variational")
    } else {
        model.into()
    }
}

/// The zero-flow baseline.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ZeroFlow {
    pub epe: f64,
    pub ae_deg: f64,
    pub px1: f64,
    pub px3: f64,
    pub px5: f64,
    /// Its EPE by speed class: each class's mean ground-truth speed.
    #[serde(default)]
    pub by_speed: EpeBySpeed,
}

/// One pair's scores: its size, how many pixels have known flow, the mean ground-truth speed
/// over them (which is also the zero-flow EPE), and one row per iteration count, timed on this
/// pair alone (`ms_per_pair` is this pair's time).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PairEval {
    pub name: String,
    pub width: usize,
    pub height: usize,
    pub pixels: u64,
    pub mean_gt: f64,
    pub rows: Vec<EvalRow>,
    pub zero_flow: ZeroFlow,
}

/// `report.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct EvalReport {
    pub model: String,
    pub parameters: usize,
    pub data: String,
    pub pairs: usize,
    pub pixels: u64,
    pub rows: Vec<EvalRow>,
    pub zero_flow: ZeroFlow,
    /// The same scores for each pair (absent in reports of older versions).
    #[serde(default)]
    pub per_pair: Vec<PairEval>,
}

impl From<FlowScores> for ZeroFlow {
    fn from(s: FlowScores) -> Self {
        ZeroFlow {
            epe: s.epe,
            ae_deg: s.ae_deg,
            px1: s.px1,
            px3: s.px3,
            px5: s.px5,
            by_speed: s.by_speed,
        }
    }
}

impl EvalRow {
    /// The row of `iters` iterations with scores `s` and `ms` milliseconds per pair.
    pub fn of(iters: usize, refined: bool, s: &FlowScores, ms: f64) -> Self {
        EvalRow {
            iters,
            refined,
            epe: s.epe,
            ae_deg: s.ae_deg,
            px1: s.px1,
            px3: s.px3,
            px5: s.px5,
            ms_per_pair: ms,
            by_speed: s.by_speed,
        }
    }
}

/// Mean scores of `model` on (up to `max_pairs` of) `data` at `iters` iterations.
pub fn evaluate_dataset(
    model: &Mms,
    cfg: &MmsConfig,
    data: &FlowDataset,
    iters: usize,
    max_pairs: usize,
    device: &Device,
) -> Result<FlowScores> {
    let n = data.pairs.len().min(max_pairs.max(1));
    evaluate_pairs(model, cfg, n, |i| data.load(i), iters, device)
}

/// [`evaluate_dataset`] on `n` pairs given by `load` (images and ground truth).
pub fn evaluate_pairs(
    model: &Mms,
    cfg: &MmsConfig,
    n: usize,
    load: impl Fn(usize) -> Result<(Image, Image, Flow)>,
    iters: usize,
    device: &Device,
) -> Result<FlowScores> {
    let mut sums = FlowErrorSums::default();
    for i in 0..n {
        let (a, b, gt) = load(i)?;
        let pred = predict_flow(model, cfg, &a, &b, iters, device)?;
        sums.add(&pred, &gt, None)?;
    }
    Ok(sums.scores())
}

/// Evaluates the predictor's network on every pair of `data` for each count in `iters`, and,
/// when the predictor has a refinement, the refined flow too (rows after the network's),
/// timing each pair; the report holds the dataset's scores (means over all known pixels) and
/// each pair's.
pub fn evaluate(predictor: &Predictor, data: &FlowDataset, iters: &[usize]) -> Result<EvalReport> {
    let (model, config, device) = (&predictor.model, &predictor.config, &predictor.device);
    if iters.is_empty() {
        return Err(Error::invalid("--iters", "empty list"));
    }
    let pairs: Vec<_> = (0..data.pairs.len())
        .map(|i| data.load(i))
        .collect::<Result<_>>()?;
    let mut zero = FlowErrorSums::default();
    let mut zero_pairs = Vec::with_capacity(pairs.len());
    for (_, _, gt) in &pairs {
        let mut z = FlowErrorSums::default();
        z.add(&Flow::zeros(gt.height(), gt.width()), gt, None)?;
        zero.merge(&z);
        zero_pairs.push(z.scores());
    }
    if zero.scores().pixels == 0 {
        return Err(Error::invalid(
            "dataset",
            format!(
                "{}: no pair holds a known ground-truth vector; there is nothing to score",
                data.root.display()
            ),
        ));
    }
    // One untimed pass so that allocation warm-up does not land on the first row.
    if let Some((a, b, _)) = pairs.first() {
        predict_flow(model, config, a, b, 1, device)?;
    }
    let mut per_pair: Vec<PairEval> = data
        .pairs
        .iter()
        .zip(&pairs)
        .zip(&zero_pairs)
        .map(|((p, (_, _, gt)), z)| PairEval {
            name: p.name.clone(),
            width: gt.width(),
            height: gt.height(),
            pixels: z.pixels,
            mean_gt: z.epe,
            rows: Vec::new(),
            zero_flow: (*z).into(),
        })
        .collect();
    let mut rows = Vec::new();
    let mut refined_rows = Vec::new();
    // Each pair's refined rows, which follow its network rows.
    let mut pair_refined: Vec<Vec<EvalRow>> = vec![Vec::new(); per_pair.len()];
    for &n in iters {
        let (mut sums, mut refined_sums) = (FlowErrorSums::default(), FlowErrorSums::default());
        let (mut seconds, mut refined_seconds) = (0.0, 0.0);
        for (((a, b, gt), pair), refined) in pairs
            .iter()
            .zip(per_pair.iter_mut())
            .zip(pair_refined.iter_mut())
        {
            let t = Instant::now();
            let pred = predictor.predict_network(a, b, n)?;
            let dt = t.elapsed().as_secs_f64();
            seconds += dt;
            let mut one = FlowErrorSums::default();
            one.add(&pred, gt, None)?;
            sums.merge(&one);
            pair.rows
                .push(EvalRow::of(n, false, &one.scores(), 1e3 * dt));
            if predictor.refine.is_some() {
                let t = Instant::now();
                let fine = predictor.refined(a, b, pred)?;
                let dt = dt + t.elapsed().as_secs_f64();
                refined_seconds += dt;
                let mut one = FlowErrorSums::default();
                one.add(&fine, gt, None)?;
                refined_sums.merge(&one);
                refined.push(EvalRow::of(n, true, &one.scores(), 1e3 * dt));
            }
        }
        let k = 1e3 / pairs.len() as f64;
        rows.push(EvalRow::of(n, false, &sums.scores(), k * seconds));
        if predictor.refine.is_some() {
            refined_rows.push(EvalRow::of(
                n,
                true,
                &refined_sums.scores(),
                k * refined_seconds,
            ));
        }
    }
    rows.append(&mut refined_rows);
    for (pair, mut refined) in per_pair.iter_mut().zip(pair_refined) {
        pair.rows.append(&mut refined);
    }
    let z = zero.scores();
    Ok(EvalReport {
        model: config.name.clone(),
        parameters: super::weights::parameter_count(model),
        data: data.root.display().to_string(),
        pairs: pairs.len(),
        pixels: z.pixels,
        rows,
        zero_flow: z.into(),
        per_pair,
    })
}

impl EvalReport {
    /// The table, like Table S4 with a time column, and the EPE by ground-truth speed in
    /// MPI-Sintel's classes.
    pub fn markdown(&self) -> String {
        let mut s = format!(
            "{} ({} parameters) on {} pairs of {}\n\n| iterations | EPE | AE (°) | 1 px | 3 px | 5 px | EPE s0-10 | s10-40 | s40+ | ms per pair |\n|---|---|---|---|---|---|---|---|---|---|\n",
            self.model, self.parameters, self.pairs, self.data
        );
        for r in &self.rows {
            let refined = if r.refined { " + variational" } else { "" };
            s += &format!(
                "| {}{refined} | {:.3} | {:.2} | {:.3} | {:.3} | {:.3} | {} | {:.0} |\n",
                r.iters,
                r.epe,
                r.ae_deg,
                r.px1,
                r.px3,
                r.px5,
                speed_cells(&r.by_speed),
                r.ms_per_pair
            );
        }
        let z = &self.zero_flow;
        s += &format!(
            "| zero flow | {:.3} | {:.2} | {:.3} | {:.3} | {:.3} | {} | 0 |\n",
            z.epe,
            z.ae_deg,
            z.px1,
            z.px3,
            z.px5,
            speed_cells(&z.by_speed)
        );
        s
    }
}

/// The three speed classes' EPE as table cells, "–" for a class without pixels.
fn speed_cells(b: &EpeBySpeed) -> String {
    (0..3)
        .map(|c| b.get(c).map_or_else(|| "–".into(), |v| format!("{v:.3}")))
        .collect::<Vec<String>>()
        .join(" | ")
}
