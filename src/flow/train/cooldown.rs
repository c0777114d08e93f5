//! The cool-down of a run that has no end in sight (Note S11 training as a campaign): a
//! warmup–stable–decay schedule. The campaign's one-cycle schedule spans far more steps than a
//! session takes, so its weights stand at the peak learning rate, where they swing by more than
//! their differences; a cool-down branches off the run's checkpoint (weights, AdamW's moments,
//! data order) and takes the rate down to zero over a fixed number of steps, leaving the run
//! itself to go on. The decay is 1 − √t of the schedule's rate (t from 0 to 1 over the
//! cool-down), the form Hägele et al. (2024, "Scaling laws and compute-optimal training beyond
//! fixed training durations") found to match or beat linear decay and a full cosine schedule.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// A cool-down of `steps` steps starting at step `start` of its run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Cooldown {
    pub start: usize,
    pub steps: usize,
}

impl Cooldown {
    /// A cool-down of `steps` from `start` within a run of `total` steps: at least one step, and
    /// ending no later than the run's own schedule.
    pub fn new(start: usize, steps: usize, total: usize) -> Result<Self> {
        if steps == 0 {
            return Err(Error::invalid(
                "--cooldown",
                "expected at least 1 step, got 0",
            ));
        }
        if start.saturating_add(steps) > total {
            return Err(Error::invalid(
                "--cooldown",
                format!(
                    "{steps} steps from step {start} pass the run's last step ({total}); at \
                     most {} are left",
                    total.saturating_sub(start)
                ),
            ));
        }
        Ok(Self { start, steps })
    }

    /// The step after the cool-down's last one: where its run ends.
    pub fn end(&self) -> usize {
        self.start + self.steps
    }

    /// The factor on the schedule's learning rate at `step` (0-based): 1 before the cool-down,
    /// 1 − √((step − start) / steps) during it (1 at its first step, above 0 at its last).
    pub fn factor(&self, step: usize) -> f64 {
        if step < self.start {
            return 1.0;
        }
        let t = ((step - self.start) as f64 / self.steps as f64).min(1.0);
        1.0 - t.sqrt()
    }
}

/// The factor of an optional cool-down: 1 without one.
pub fn factor(step: usize, cooldown: Option<Cooldown>) -> f64 {
    cooldown.map_or(1.0, |c| c.factor(step))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rate_falls_as_one_minus_the_root_of_the_share_done() {
        let c = Cooldown::new(1000, 100, 20_000).unwrap();
        assert_eq!(c.end(), 1100);
        assert_eq!(c.factor(999), 1.0);
        assert_eq!(c.factor(1000), 1.0);
        assert!((c.factor(1025) - 0.5).abs() < 1e-12);
        assert!((c.factor(1064) - 0.2).abs() < 1e-12);
        // Every step taken has a positive rate, and each a lower one than the step before.
        let rates: Vec<f64> = (1000..1100).map(|s| c.factor(s)).collect();
        assert!(rates.windows(2).all(|w| w[1] < w[0]));
        assert!(rates[99] > 0.0 && rates[99] < 0.11);
        assert_eq!(c.factor(1100), 0.0);
        assert_eq!(factor(5, None), 1.0);
    }

    #[test]
    fn a_cool_down_must_fit_in_its_run() {
        assert!(Cooldown::new(0, 20_000, 20_000).is_ok());
        let err = Cooldown::new(19_950, 100, 20_000).unwrap_err().to_string();
        assert!(
            err.contains("--cooldown") && err.contains("at most 50"),
            "{err}"
        );
        let err = Cooldown::new(10, 0, 100).unwrap_err().to_string();
        assert!(err.contains("at least 1"), "{err}");
    }
}
