//! Evaluation: EPE, angular error and 1/3/5-px accuracy for several iteration counts, each with
//! its run time per pair, against the zero-flow baseline — error against run time (Table S4).

use std::time::Instant;

use burn::prelude::*;
use serde::{Deserialize, Serialize};

use super::data::FlowDataset;
use super::infer::predict_flow;
use super::metrics::{FlowErrorSums, FlowScores};
use super::model::{Mms, MmsConfig};
use crate::error::{Error, Result};
use crate::types::Flow;

/// One row of the report.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct EvalRow {
    pub iters: usize,
    pub epe: f64,
    pub ae_deg: f64,
    pub px1: f64,
    pub px3: f64,
    pub px5: f64,
    pub ms_per_pair: f64,
}

/// The zero-flow baseline.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ZeroFlow {
    pub epe: f64,
    pub ae_deg: f64,
    pub px1: f64,
    pub px3: f64,
    pub px5: f64,
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
    let mut sums = FlowErrorSums::default();
    for i in 0..data.pairs.len().min(max_pairs.max(1)) {
        let (a, b, gt) = data.load(i)?;
        let pred = predict_flow(model, cfg, &a, &b, iters, device)?;
        sums.add(&pred, &gt, None)?;
    }
    Ok(sums.scores())
}

/// Evaluates `model` on every pair of `data` for each count in `iters`, timing each pair.
pub fn evaluate(
    model: &Mms,
    config: &MmsConfig,
    data: &FlowDataset,
    iters: &[usize],
    device: &Device,
) -> Result<EvalReport> {
    if iters.is_empty() {
        return Err(Error::invalid("--iters", "empty list"));
    }
    let pairs: Vec<_> = (0..data.pairs.len())
        .map(|i| data.load(i))
        .collect::<Result<_>>()?;
    let mut zero = FlowErrorSums::default();
    for (_, _, gt) in &pairs {
        zero.add(&Flow::zeros(gt.height(), gt.width()), gt, None)?;
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
    let mut rows = Vec::new();
    for &n in iters {
        let mut sums = FlowErrorSums::default();
        let mut seconds = 0.0;
        for (a, b, gt) in &pairs {
            let t = Instant::now();
            let pred = predict_flow(model, config, a, b, n, device)?;
            seconds += t.elapsed().as_secs_f64();
            sums.add(&pred, gt, None)?;
        }
        let s = sums.scores();
        rows.push(EvalRow {
            iters: n,
            epe: s.epe,
            ae_deg: s.ae_deg,
            px1: s.px1,
            px3: s.px3,
            px5: s.px5,
            ms_per_pair: 1e3 * seconds / pairs.len() as f64,
        });
    }
    let z = zero.scores();
    Ok(EvalReport {
        model: config.name.clone(),
        parameters: super::weights::parameter_count(model),
        data: data.root.display().to_string(),
        pairs: pairs.len(),
        pixels: z.pixels,
        rows,
        zero_flow: ZeroFlow {
            epe: z.epe,
            ae_deg: z.ae_deg,
            px1: z.px1,
            px3: z.px3,
            px5: z.px5,
        },
    })
}

impl EvalReport {
    /// The table, like Table S4 with a time column.
    pub fn markdown(&self) -> String {
        let mut s = format!(
            "{} ({} parameters) on {} pairs of {}\n\n| iterations | EPE | AE (°) | 1 px | 3 px | 5 px | ms per pair |\n|---|---|---|---|---|---|---|\n",
            self.model, self.parameters, self.pairs, self.data
        );
        for r in &self.rows {
            s += &format!(
                "| {} | {:.3} | {:.2} | {:.3} | {:.3} | {:.3} | {:.0} |\n",
                r.iters, r.epe, r.ae_deg, r.px1, r.px3, r.px5, r.ms_per_pair
            );
        }
        let z = &self.zero_flow;
        s += &format!(
            "| zero flow | {:.3} | {:.2} | {:.3} | {:.3} | {:.3} | 0 |\n",
            z.epe, z.ae_deg, z.px1, z.px3, z.px5
        );
        s
    }
}
