//! The training stamp a run writes into its weights files (Note S11 training as a campaign):
//! where in its schedule the weights stand (step of steps, pairs seen), the config that made
//! them and the fingerprint of their data (no wall-clock time: equal runs write equal files), so that a run can go on from a weights file alone — a warm
//! restart, when the full checkpoint (optimiser state) is gone — on the same schedule, after a
//! short learning-rate warm-up while AdamW's moments are rebuilt.

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::config::TrainConfig;
use super::cooldown::Cooldown;
use crate::error::{Error, Result};
use crate::flow::data::DataFingerprint;
use crate::flow::weights;

/// Metadata key of the stamp in a weights file.
pub const STAMP_KEY: &str = "pins.training";

/// Where a weights file stands in the run that made it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrainingStamp {
    /// Steps taken.
    pub step: usize,
    /// Steps the run's schedule spans.
    pub steps: usize,
    /// Training pairs seen (steps × batch).
    pub pairs_seen: u64,
    /// The run's config (a setting added to pins later reads as its default, so the weights
    /// of a run stay continuable across versions).
    pub config: TrainConfig,
    /// The training data's fingerprint (pairs, and a hash of their names and sizes).
    pub data: DataFingerprint,
    /// The cool-down these weights come from, if any: they stand off the run's own schedule,
    /// which goes on from its checkpoint, not from them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cooldown: Option<Cooldown>,
}

impl TrainingStamp {
    /// The stamp as a metadata entry.
    pub fn entry(&self) -> Result<(&'static str, String)> {
        let text = serde_json::to_string(self)
            .map_err(|e| Error::invalid("training stamp", e.to_string()))?;
        Ok((STAMP_KEY, text))
    }

    /// The stamp of a weights file's bytes, if it has one.
    pub fn read(bytes: &[u8], what: &Path) -> Result<Option<Self>> {
        let Some(text) = weights::read_metadata(bytes, what, STAMP_KEY)? else {
            return Ok(None);
        };
        serde_json::from_str(&text)
            .map(Some)
            .map_err(|e| Error::format(what, format!("{STAMP_KEY}: {e}")))
    }

    /// The step a warm restart of `config` on `data` from these weights starts at: the
    /// stamp's, when the weights were made by this very config on the same data and have
    /// steps left; otherwise an error that names what differs.
    pub fn restart_step(
        &self,
        config: &TrainConfig,
        data: &DataFingerprint,
        what: &Path,
    ) -> Result<usize> {
        if let Some(c) = self.cooldown {
            return Err(Error::invalid(
                "--continue-from",
                format!(
                    "{} comes from a cool-down (steps {}–{}), off the run's schedule: a warm \
                     restart continues the run from its own weights; use --init to fine-tune \
                     from these",
                    what.display(),
                    c.start,
                    c.end()
                ),
            ));
        }
        let diffs = super::checkpoint::config_differences(&self.config, config);
        if !diffs.is_empty() {
            return Err(Error::invalid(
                "--continue-from",
                format!(
                    "{} was trained with another config ({} → this run's): {}; a warm restart \
                     continues the same schedule: use --init to fine-tune from it on a new one",
                    what.display(),
                    "its stamp",
                    diffs.join(", ")
                ),
            ));
        }
        if *data != self.data {
            return Err(Error::invalid(
                "--continue-from",
                format!(
                    "{} was trained on other data ({}) than --data holds ({}): a warm \
                     restart continues the same run; use --init to fine-tune from it on new \
                     data",
                    what.display(),
                    self.data.describe(),
                    data.describe()
                ),
            ));
        }
        if self.step >= config.steps {
            return Err(Error::invalid(
                "--continue-from",
                format!(
                    "{} is the end of its run ({} of {} steps): nothing is left to continue",
                    what.display(),
                    self.step,
                    config.steps
                ),
            ));
        }
        Ok(self.step)
    }
}

/// The learning-rate factor `warmup` steps after a warm restart at step `restart`: from 1/25
/// (the one-cycle schedule's own starting fraction) up to 1, linearly; 1 when the run did not
/// restart or the warm-up is over.
pub fn restart_factor(step: usize, restart: Option<usize>, warmup: usize) -> f64 {
    match restart {
        Some(r) if warmup > 0 && step >= r && step - r < warmup => {
            let t = (step - r) as f64 / warmup as f64;
            1.0 / 25.0 + (1.0 - 1.0 / 25.0) * t
        }
        _ => 1.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_warm_up_after_a_restart_rises_from_a_25th_to_the_schedule() {
        assert_eq!(restart_factor(500, None, 100), 1.0);
        assert!((restart_factor(500, Some(500), 100) - 0.04).abs() < 1e-12);
        assert!((restart_factor(550, Some(500), 100) - 0.52).abs() < 1e-12);
        assert_eq!(restart_factor(600, Some(500), 100), 1.0);
        assert_eq!(restart_factor(500, Some(500), 0), 1.0);
    }

    #[test]
    fn a_restart_needs_the_same_config_and_steps_left() {
        let config = TrainConfig::default();
        let stamp = TrainingStamp {
            step: 700,
            steps: config.steps,
            pairs_seen: 2800,
            config: config.clone(),
            data: DataFingerprint {
                pairs: 10,
                sha256: "ab".repeat(32),
            },
            cooldown: None,
        };
        let data = stamp.data.clone();
        let p = Path::new("w.safetensors");
        assert_eq!(stamp.restart_step(&config, &data, p).unwrap(), 700);
        let other_data = DataFingerprint {
            pairs: 11,
            ..data.clone()
        };
        let err = stamp
            .restart_step(&config, &other_data, p)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("other data") && err.contains("11 pairs"),
            "{err}"
        );
        let other = TrainConfig {
            lr: 1e-3,
            ..config.clone()
        };
        let err = stamp
            .restart_step(&other, &data, p)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("another config") && err.contains("--init"),
            "{err}"
        );
        let done = TrainingStamp {
            step: config.steps,
            ..stamp
        };
        let err = done
            .restart_step(&config, &data, p)
            .unwrap_err()
            .to_string();
        assert!(err.contains("nothing is left"), "{err}");
        let cooled = TrainingStamp {
            step: 800,
            cooldown: Some(Cooldown::new(700, 100, config.steps).unwrap()),
            ..done
        };
        let err = cooled
            .restart_step(&config, &data, p)
            .unwrap_err()
            .to_string();
        assert!(err.contains("cool-down (steps 700–800)"), "{err}");
    }
}
