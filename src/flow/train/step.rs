//! One training step (Note S11): the batch of step s — a function of (seed, s) alone, so that
//! resuming replays the same data order — the forward pass over all refinements, the sequence
//! loss of Eq. S16, the backward pass, global gradient clipping and the AdamW update. A
//! non-finite loss or gradient norm stops the run.

use burn::optim::{GradientsAccumulator, GradientsParams, ModuleOptimizer};
use burn::prelude::*;

use super::checkpoint;
use super::clip::clip_global_norm;
use super::config::TrainConfig;
use super::options::TrainOptions;
use super::source::TrainData;
use crate::error::{Error, Result};
use crate::flow::data::{Batch, Example, make_example};
use crate::flow::loss::{mean_epe, moving_weights, sequence_loss};
use crate::flow::model::Mms;
use crate::rng;

/// What one step measured.
#[derive(Clone, Copy, Debug)]
pub struct StepStats {
    /// The sequence loss (Eq. S16).
    pub loss: f32,
    /// Mean end-point error of the last prediction.
    pub epe: f32,
    /// The global gradient norm before clipping.
    pub grad_norm: f64,
}

/// The batch of step `step`: `batch_size` random crops of random training pairs, augmented.
///
/// # Shapes
/// images `[B, 3, h, w]`, flow `[B, 2, h, w]`, valid `[B, 1, h, w]` for the crop `[h, w]`
pub fn batch(
    config: &TrainConfig,
    data: &TrainData,
    step: usize,
    device: &Device,
) -> Result<Batch> {
    Batch::stack(examples(config, data, step)?, device)
}

/// The examples of step `step`'s batch, in order: a function of (seed, step) alone, whatever
/// the number of devices they are then spread over.
pub fn examples(config: &TrainConfig, data: &TrainData, step: usize) -> Result<Vec<Example>> {
    let mut r = rng::stream(config.seed, &[rng::purpose::TRAIN, step as u64]);
    let mut examples = Vec::with_capacity(config.batch_size);
    // The step's crop: its first pair's (a stream's source may have its own); the other slots
    // draw among the sources of that crop, so that the batch is of one size.
    let mut crop = None;
    for slot in 0..config.batch_size {
        let (a, b, f, c) = data.train_pair(config, step, slot, crop, &mut r)?;
        let c = *crop.get_or_insert(c);
        examples.push(make_example(
            &a,
            &b,
            &f,
            (c[0], c[1]),
            &config.augment,
            &mut r,
        )?);
    }
    Ok(examples)
}

/// Device `rank`'s share of a batch of `b` examples over `n` devices: a contiguous block,
/// `[rank·b/n, (rank+1)·b/n)`, so the shares differ by at most one example.
pub fn share(b: usize, n: usize, rank: usize) -> std::ops::Range<usize> {
    (rank * b / n)..((rank + 1) * b / n)
}

/// Step `step` on `examples` spread over `devices` (data parallel; the first is the main device,
/// which holds the model and the optimiser): each device runs a fork of the model on its share
/// (`share`), its loss weighted by its share of the batch so that the weighted gradients sum to
/// the whole batch's; the gradients are moved to the main device and summed, then clipped once
/// and applied in one optimiser step. With one device this is `take` on the whole batch.
#[allow(clippy::too_many_arguments)]
pub fn take_parallel(
    model: Mms,
    optim: &mut ModuleOptimizer,
    examples: Vec<Example>,
    devices: &[Device],
    config: &TrainConfig,
    lr: f64,
    step: usize,
    opts: &TrainOptions,
) -> Result<(Mms, StepStats)> {
    let b = examples.len();
    if devices.len() <= 1 {
        let device = devices
            .first()
            .cloned()
            .unwrap_or_else(|| model.devices()[0].clone());
        return take(
            model,
            optim,
            Batch::stack(examples, &device)?,
            config,
            lr,
            step,
            opts,
        );
    }
    if b < devices.len() {
        return Err(Error::invalid(
            "--devices",
            format!(
                "{} devices need a batch_size of at least {}, got {b}",
                devices.len(),
                devices.len()
            ),
        ));
    }
    let main = devices[0].clone();
    let mut shares: Vec<Vec<Example>> = Vec::with_capacity(devices.len());
    let mut rest = examples;
    for rank in (0..devices.len()).rev() {
        let r = share(b, devices.len(), rank);
        shares.push(rest.split_off(r.start));
    }
    shares.reverse();
    // Each device: forward, weighted loss, backward, its gradients on the main device.
    type RankOut = (GradientsParams, f32, f32, f32);
    let outs: Vec<Result<RankOut>> = std::thread::scope(|scope| {
        let handles: Vec<_> = shares
            .into_iter()
            .zip(devices)
            .map(|(part, device)| {
                let (model, main) = (&model, &main);
                scope.spawn(move || -> Result<RankOut> {
                    let weight = part.len() as f32 / b as f32;
                    let replica = model.clone().fork(device);
                    let batch = Batch::stack(part, device)?;
                    let preds = replica.forward(batch.img1, batch.img2, config.iters, true);
                    let weights = moving_weights(
                        batch.flow.clone(),
                        batch.valid.clone(),
                        config.moving_weight,
                    );
                    let loss = sequence_loss(&preds, batch.flow.clone(), weights, config.rho)
                        .mul_scalar(weight);
                    let loss_value: f32 = loss.clone().into_scalar();
                    let (num, den) = preds
                        .last()
                        .map(|p| epe_sums(p.clone(), batch.flow, batch.valid))
                        .unwrap_or((f32::NAN, 1.0));
                    let grads = GradientsParams::from_grads(loss.backward(), &replica)
                        .to_device(main, &replica);
                    Ok((grads, loss_value, num, den))
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| {
                h.join()
                    .unwrap_or_else(|_| Err(Error::invalid("training", "a device's step panicked")))
            })
            .collect()
    });
    let mut acc = GradientsAccumulator::<Mms>::new();
    let (mut loss_value, mut num, mut den) = (0.0f32, 0.0f32, 0.0f32);
    for out in outs {
        let (grads, l, n, d) = out?;
        acc.accumulate(&model, grads);
        loss_value += l;
        num += n;
        den += d;
    }
    if !loss_value.is_finite() {
        return Err(non_finite_loss(loss_value, step, opts));
    }
    let (model, grad_norm) = clip_and_step(model, optim, acc.grads(), config, lr, step)?;
    Ok((
        model,
        StepStats {
            loss: loss_value,
            epe: num / den.max(1.0),
            grad_norm,
        },
    ))
}

/// Global-norm clipping and one optimiser step; a non-finite gradient norm stops the run.
fn clip_and_step(
    model: Mms,
    optim: &mut ModuleOptimizer,
    mut grads: GradientsParams,
    config: &TrainConfig,
    lr: f64,
    step: usize,
) -> Result<(Mms, f64)> {
    let grad_norm = clip_global_norm(&model, &mut grads, config.clip);
    if !grad_norm.is_finite() {
        return Err(Error::invalid(
            "training",
            format!(
                "gradient norm became {grad_norm} at step {step}; stopped, last checkpoint kept"
            ),
        ));
    }
    Ok((optim.step(lr, model, grads), grad_norm))
}

/// The error of a non-finite loss, naming the last good checkpoint.
fn non_finite_loss(loss_value: f32, step: usize, opts: &TrainOptions) -> Error {
    Error::invalid(
        "training",
        format!(
            "loss became {loss_value} at step {step}; stopped. The last good checkpoint (step {}) is kept in {}",
            checkpoint::read(&opts.out)
                .ok()
                .flatten()
                .map(|c| c.0.step)
                .unwrap_or(0),
            checkpoint::dir(&opts.out).display()
        ),
    )
}

/// Σ EPE·valid and Σ valid of the last prediction, for a batch spread over devices.
///
/// # Shapes
/// `[B, 2, H, W]`, `[B, 2, H, W]`, `[B, 1, H, W]` → (scalar, scalar)
fn epe_sums(pred: Tensor<4>, gt: Tensor<4>, valid: Tensor<4>) -> (f32, f32) {
    let epe = (pred - gt).powi_scalar(2).sum_dim(1).sqrt(); // [B, 1, H, W]
    let num: f32 = (epe * valid.clone()).sum().into_scalar();
    (num, valid.sum().into_scalar())
}

/// Step `step` on `batch` at learning rate `lr`: the updated network and what the step
/// measured.
pub fn take(
    model: Mms,
    optim: &mut ModuleOptimizer,
    batch: Batch,
    config: &TrainConfig,
    lr: f64,
    step: usize,
    opts: &TrainOptions,
) -> Result<(Mms, StepStats)> {
    let preds = model.forward(batch.img1, batch.img2, config.iters, true);
    let weights = moving_weights(
        batch.flow.clone(),
        batch.valid.clone(),
        config.moving_weight,
    );
    let loss = sequence_loss(&preds, batch.flow.clone(), weights, config.rho);
    let loss_value: f32 = loss.clone().into_scalar();
    if !loss_value.is_finite() {
        return Err(non_finite_loss(loss_value, step, opts));
    }
    let epe = preds
        .last()
        .map(|p| mean_epe(p.clone(), batch.flow, batch.valid))
        .unwrap_or(f32::NAN);
    let grads = GradientsParams::from_grads(loss.backward(), &model);
    let (model, grad_norm) = clip_and_step(model, optim, grads, config, lr, step)?;
    let stats = StepStats {
        loss: loss_value,
        epe,
        grad_norm,
    };
    Ok((model, stats))
}
