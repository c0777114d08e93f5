//! `pins bench-flow`: inference and one training step of the MMS network (random weights) at a
//! given size, timed as a median after a warm-up, with the process's peak memory — one
//! measurement per process, so `scripts/bench_flow_compare.sh` can set it beside PyTorch's RAFT.

use burn::optim::{AdamWConfig, GradientsParams};
use burn::prelude::*;
use burn::tensor::Distribution;
use serde::Serialize;

use super::bench::median_ms;
use crate::error::{Error, Result};
use crate::flow::loss::sequence_loss;
use crate::flow::model::{Mms, MmsConfig};
use crate::flow::train::clip::clip_global_norm;
use crate::flow::weights::parameter_count;

/// One measurement, printed as a JSON line.
#[derive(Clone, Debug, Serialize)]
pub struct FlowBenchRow {
    pub tool: String,
    pub mode: String,
    pub height: usize,
    pub width: usize,
    pub batch: usize,
    pub iters: usize,
    pub ms: f64,
    pub peak_rss_mb: f64,
    pub params: usize,
}

/// Peak resident memory of this process in MB (VmHWM), 0 where /proc is not available.
pub fn peak_rss_mb() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse::<f64>().ok())
        })
        .map(|kb| kb / 1024.0)
        .unwrap_or(0.0)
}

/// Runs one measurement on `device`: `mode` is `infer` (batch 1) or `train` (batch 2, AdamW
/// step).
pub fn run(
    model: &str,
    mode: &str,
    height: usize,
    width: usize,
    iters: usize,
    reps: usize,
    device: &Device,
) -> Result<FlowBenchRow> {
    let cfg = MmsConfig::named(model)?;
    if !height.is_multiple_of(8)
        || !width.is_multiple_of(8)
        || height < cfg.min_side()
        || width < cfg.min_side()
    {
        return Err(Error::invalid(
            "size",
            format!(
                "{height}x{width}: sides must be multiples of 8 and at least {}",
                cfg.min_side()
            ),
        ));
    }
    let (ms, batch, params) = match mode {
        "infer" => {
            let device = device.clone();
            let net = Mms::new(&cfg, &device);
            let a = Tensor::<4>::random([1, 3, height, width], Distribution::Default, &device);
            let b = Tensor::<4>::random([1, 3, height, width], Distribution::Default, &device);
            let ms = median_ms(reps, || {
                let out = net.forward(a.clone(), b.clone(), iters, false);
                // Reading the result forces every op to run.
                out.last().map(|t| t.clone().sum().into_scalar::<f32>())
            });
            (ms, 1, parameter_count(&net))
        }
        "train" => {
            let device = device.clone().autodiff();
            let mut net = Mms::new(&cfg, &device);
            let params = parameter_count(&net);
            let mut optim = AdamWConfig::new().init();
            let batch = 2;
            let a = Tensor::<4>::random([batch, 3, height, width], Distribution::Default, &device);
            let b = Tensor::<4>::random([batch, 3, height, width], Distribution::Default, &device);
            let gt = Tensor::<4>::random(
                [batch, 2, height, width],
                Distribution::Normal(0.0, 4.0),
                &device,
            );
            let valid = Tensor::<4>::ones([batch, 1, height, width], &device);
            let tensors = parameter_tensors(&net);
            // A step counts only if its backward pass gave a finite gradient for every
            // parameter tensor: the norm reads every gradient, so a backend whose backward
            // fails (or silently skips a layer) is reported instead of timed.
            let mut failure: Option<String> = None;
            let mut step = || {
                let preds = net.forward(a.clone(), b.clone(), iters, true);
                let loss = sequence_loss(&preds, gt.clone(), valid.clone(), 0.8);
                let mut grads = GradientsParams::from_grads(loss.backward(), &net);
                let (got, norm) = (
                    grads.len(),
                    clip_global_norm(&net, &mut grads, f64::INFINITY),
                );
                if got != tensors || !norm.is_finite() {
                    failure.get_or_insert(format!(
                        "the backward pass gave {got} of {tensors} gradients, norm {norm}"
                    ));
                }
                net = optim.step(4e-4, net.clone(), grads);
            };
            let ms = median_ms(reps, &mut step);
            if let Some(f) = failure {
                return Err(Error::invalid("bench-flow --mode train", f));
            }
            (ms, batch, params)
        }
        other => {
            return Err(Error::invalid(
                "--mode",
                format!("{other:?}: use infer or train"),
            ));
        }
    };
    Ok(FlowBenchRow {
        tool: format!("pins {model}"),
        mode: mode.to_string(),
        height,
        width,
        batch,
        iters,
        ms,
        peak_rss_mb: peak_rss_mb(),
        params,
    })
}

/// The number of parameter tensors of `module` (each should get a gradient).
fn parameter_tensors<M: burn::module::Module>(module: &M) -> usize {
    struct Count(usize);
    impl burn::module::ModuleVisitor for Count {
        fn visit_float<const D: usize>(&mut self, _: &burn::module::Param<Tensor<D>>) {
            self.0 += 1;
        }
    }
    let mut c = Count(0);
    module.visit(&mut c);
    c.0
}
