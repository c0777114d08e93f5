//! Training configuration (Note S11 and RAFT's recipe, sized for a CPU): every default here.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::flow::data::AugmentConfig;
use crate::flow::model::MmsConfig;

/// How a run trains. Unknown keys are rejected.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrainConfig {
    /// `mms-small` or `mms`.
    pub model: String,
    /// Total optimiser steps (the one-cycle schedule spans them).
    pub steps: usize,
    pub batch_size: usize,
    /// Random crop `[H, W]`, multiples of 8.
    pub crop: [usize; 2],
    /// Refinement iterations while training.
    pub iters: usize,
    /// Peak learning rate of the one-cycle schedule.
    pub lr: f64,
    /// Fraction of the steps spent warming up from lr/25.
    pub pct_start: f64,
    pub weight_decay: f64,
    pub epsilon: f64,
    /// Global gradient-norm clip (over all parameters, as torch's clip_grad_norm_).
    pub clip: f64,
    /// ρ of Eq. S16.
    pub rho: f32,
    /// Weight in the loss of the pixels whose true motion exceeds 0.5 px, against 1 for the
    /// still ones (1: RAFT's plain mean over pixels). On clips of small movers over a still
    /// background the movers are 1–3 % of the pixels, and the plain mean is lowest for zero
    /// flow everywhere: a network fine-tuned on them stops seeing its movers.
    pub moving_weight: f32,
    /// Share of the dataset held out for validation.
    pub val_fraction: f64,
    /// Validate every this many steps (and at the end).
    pub val_every: usize,
    /// At most this many validation pairs per evaluation.
    pub val_max_pairs: usize,
    /// Iterations used when validating.
    pub val_iters: usize,
    /// Write a checkpoint every this many steps (and at the end, and at least every ten
    /// minutes: [`super::budget::CHECKPOINT_INTERVAL`]).
    pub checkpoint_every: usize,
    /// Steps of learning-rate warm-up after a warm restart (`--continue-from`: the weights
    /// without AdamW's moments), from 1/25 of the schedule's rate up to it.
    pub restart_warmup: usize,
    /// Seed of the data order and augmentation; step s draws from (seed, s) alone.
    pub seed: u64,
    pub augment: AugmentConfig,
}

impl Default for TrainConfig {
    fn default() -> Self {
        Self {
            model: "mms-small".into(),
            steps: 2000,
            batch_size: 4,
            crop: [128, 160],
            iters: 8,
            lr: 4e-4,
            pct_start: 0.05,
            weight_decay: 1e-4,
            epsilon: 1e-8,
            clip: 1.0,
            rho: 0.8,
            moving_weight: 1.0,
            val_fraction: 0.1,
            val_every: 250,
            val_max_pairs: 16,
            val_iters: 12,
            checkpoint_every: 100,
            restart_warmup: 100,
            seed: 0,
            augment: AugmentConfig::default(),
        }
    }
}

impl TrainConfig {
    /// Reads a JSON config, naming the file on error.
    pub fn from_file(path: &std::path::Path) -> Result<Self> {
        let cfg: Self = crate::io::read_json(path)?;
        cfg.validate().map_err(|e| crate::io::in_config(path, e))?;
        Ok(cfg)
    }

    /// The model's config.
    pub fn model_config(&self) -> Result<MmsConfig> {
        MmsConfig::named(&self.model)
    }

    pub fn validate(&self) -> Result<()> {
        self.model_config()?;
        let finite_in = |v: f64, lo: f64, hi: f64| v.is_finite() && v > lo && v <= hi;
        let checks: [(&str, bool, &str); 14] = [
            ("steps", self.steps > 0, "at least 1"),
            (
                "batch_size",
                (1..=256).contains(&self.batch_size),
                "in 1..=256",
            ),
            (
                "crop",
                crop_fits_the_network(self.crop),
                "sides that are multiples of 8, at least 64",
            ),
            ("iters", (1..=64).contains(&self.iters), "in 1..=64"),
            ("lr", finite_in(self.lr, 0.0, 1.0), "a number in (0, 1]"),
            (
                "pct_start",
                (0.0..1.0).contains(&self.pct_start),
                "a number in [0, 1)",
            ),
            (
                "weight_decay",
                self.weight_decay.is_finite() && self.weight_decay >= 0.0,
                "a finite number >= 0",
            ),
            (
                "epsilon",
                finite_in(self.epsilon, 0.0, 1.0),
                "a number in (0, 1] (AdamW divides by sqrt(v) + epsilon)",
            ),
            (
                "clip",
                finite_in(self.clip, 0.0, f64::MAX),
                "a finite number > 0",
            ),
            (
                "rho",
                finite_in(self.rho as f64, 0.0, 1.0),
                "a number in (0, 1]",
            ),
            (
                "moving_weight",
                self.moving_weight.is_finite() && (1.0..=1000.0).contains(&self.moving_weight),
                "a number in [1, 1000]",
            ),
            (
                "val_fraction",
                self.val_fraction > 0.0 && self.val_fraction < 1.0,
                "a number in (0, 1)",
            ),
            (
                "val_every/checkpoint_every",
                self.val_every > 0 && self.checkpoint_every > 0,
                "at least 1",
            ),
            ("val_iters", (1..=64).contains(&self.val_iters), "in 1..=64"),
        ];
        for (name, ok, expected) in checks {
            if !ok {
                let value = serde_json::to_value(self)
                    .ok()
                    .and_then(|v| v.get(name).map(|x| x.to_string()))
                    .unwrap_or_default();
                return Err(Error::invalid(
                    format!("train.{name}"),
                    format!("expected {expected}, got {value}"),
                ));
            }
        }
        Ok(())
    }
}

/// Whether `crop` can be trained on: sides that are multiples of 8 (the network's 1/8 grid), at
/// least 64 (the coarsest correlation level keeps a cell).
pub fn crop_fits_the_network(crop: [usize; 2]) -> bool {
    crop.iter().all(|&c| c >= 64 && c % 8 == 0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn out_of_range_values_are_named_with_their_range() {
        assert!(TrainConfig::default().validate().is_ok());
        for eps in [0.0, -1e-8, f64::NAN, f64::INFINITY] {
            let cfg = TrainConfig {
                epsilon: eps,
                ..TrainConfig::default()
            };
            let err = cfg.validate().unwrap_err().to_string();
            assert!(
                err.contains("train.epsilon") && err.contains("(0, 1]"),
                "{err}"
            );
        }
        let cfg = TrainConfig {
            crop: [100, 160],
            ..TrainConfig::default()
        };
        let err = cfg.validate().unwrap_err().to_string();
        assert!(
            err.contains("train.crop") && err.contains("[100,160]"),
            "{err}"
        );
    }
}
