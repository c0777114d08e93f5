//! Held-out validation during training (Table S4 metrics): the EPE and 1-px accuracy of the
//! current weights on the validation split; the best weights so far exported as
//! `best.safetensors`.

use burn::prelude::*;

use super::config::TrainConfig;
use super::options::TrainOptions;
use super::stamp::TrainingStamp;
use crate::error::Result;
use crate::flow::data::FlowDataset;
use crate::flow::eval::evaluate_dataset;
use crate::flow::metrics::FlowScores;
use crate::flow::model::{Mms, MmsConfig};
use crate::flow::weights;

/// The scores of `model` on `val_set`; `best` (the lowest EPE so far) updated, and the
/// weights saved with their training stamp, when they are the best yet.
pub fn validate(
    model: &Mms,
    model_config: &MmsConfig,
    val_set: &FlowDataset,
    config: &TrainConfig,
    opts: &TrainOptions,
    best: &mut Option<f64>,
    stamp: &TrainingStamp,
) -> Result<FlowScores> {
    let valid_model = model.valid();
    let scores = evaluate_dataset(
        &valid_model,
        model_config,
        val_set,
        config.val_iters,
        config.val_max_pairs,
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
