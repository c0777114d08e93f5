//! Held-out validation during training (Table S4 metrics): the EPE and 1-px accuracy of the
//! current weights on the held-out pairs (a folder's tail, or a stream's own); the best weights so far exported as
//! `best.safetensors`.

use burn::prelude::*;

use super::config::TrainConfig;
use super::options::TrainOptions;
use super::source::TrainData;
use super::stamp::TrainingStamp;
use crate::error::Result;
use crate::flow::eval::evaluate_pairs;
use crate::flow::metrics::FlowScores;
use crate::flow::model::{Mms, MmsConfig};
use crate::flow::weights;

/// The scores of `model` on the validation pairs of `data`; `best` (the lowest EPE so far) updated, and the
/// weights saved with their training stamp, when they are the best yet.
pub fn validate(
    model: &Mms,
    model_config: &MmsConfig,
    data: &TrainData,
    config: &TrainConfig,
    opts: &TrainOptions,
    best: &mut Option<f64>,
    stamp: &TrainingStamp,
) -> Result<FlowScores> {
    let valid_model = model.valid();
    let n = data.val_count(config.val_max_pairs);
    let scores = evaluate_pairs(
        &valid_model,
        model_config,
        n,
        |j| data.val_pair(j, n),
        config.val_iters,
        &opts.device,
    )?;
    if best.is_none_or(|b| scores.epe < b) {
        *best = Some(scores.epe);
        weights::save_with(
            &opts.out.join("best.safetensors"),
            &valid_model,
            model_config,
            &[stamp.entry()?],
        )?;
    }
    Ok(scores)
}
