//! One training step (Note S11): the batch of step s — a function of (seed, s) alone, so that
//! resuming replays the same data order — the forward pass over all refinements, the sequence
//! loss of Eq. S16, the backward pass, global gradient clipping and the AdamW update. A
//! non-finite loss or gradient norm stops the run.

use burn::optim::{GradientsParams, ModuleOptimizer};
use burn::prelude::*;

use super::checkpoint;
use super::clip::clip_global_norm;
use super::config::TrainConfig;
use super::trainer::TrainOptions;
use crate::error::{Error, Result};
use crate::flow::data::{Batch, FlowDataset, make_example};
use crate::flow::loss::{mean_epe, sequence_loss};
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
    train_set: &FlowDataset,
    step: usize,
    device: &Device,
) -> Result<Batch> {
    let mut r = rng::stream(config.seed, &[rng::purpose::TRAIN, step as u64]);
    let mut examples = Vec::with_capacity(config.batch_size);
    for _ in 0..config.batch_size {
        let i = rand::RngExt::random_range(&mut r, 0..train_set.pairs.len());
        let (a, b, f) = train_set.load(i)?;
        examples.push(make_example(
            &a,
            &b,
            &f,
            (config.crop[0], config.crop[1]),
            &config.augment,
            &mut r,
        )?);
    }
    Ok(Batch::stack(
        examples,
        config.crop[0],
        config.crop[1],
        device,
    ))
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
    let loss = sequence_loss(&preds, batch.flow.clone(), batch.valid.clone(), config.rho);
    let loss_value: f32 = loss.clone().into_scalar();
    if !loss_value.is_finite() {
        return Err(Error::invalid(
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
        ));
    }
    let epe = preds
        .last()
        .map(|p| mean_epe(p.clone(), batch.flow, batch.valid))
        .unwrap_or(f32::NAN);
    let mut grads = GradientsParams::from_grads(loss.backward(), &model);
    let grad_norm = clip_global_norm(&model, &mut grads, config.clip);
    if !grad_norm.is_finite() {
        return Err(Error::invalid(
            "training",
            format!(
                "gradient norm became {grad_norm} at step {step}; stopped, last checkpoint kept"
            ),
        ));
    }
    let model = optim.step(lr, model, grads);
    let stats = StepStats {
        loss: loss_value,
        epe,
        grad_norm,
    };
    Ok((model, stats))
}
