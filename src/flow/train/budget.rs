//! When a training session stops on its own (Note S11 training as a campaign): a wall-clock
//! budget (`--time-budget 2h30m`), a stop request (SIGTERM or Ctrl-C, set by the CLI), and the
//! longest a session may go without a checkpoint, so that a kill loses little.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use crate::error::{Error, Result};

/// A checkpoint is written at least this often (besides the config's `checkpoint_every`), so
/// that a killed session loses at most this much training.
pub const CHECKPOINT_INTERVAL: Duration = Duration::from_secs(10 * 60);

/// Why a session ended before its last step.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum StopReason {
    /// `--time-budget` would have been passed by the next step.
    TimeBudget,
    /// A stop was requested (SIGTERM, Ctrl-C).
    Signal,
}

impl std::fmt::Display for StopReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            StopReason::TimeBudget => "its time budget",
            StopReason::Signal => "a stop request (SIGTERM or Ctrl-C)",
        })
    }
}

/// The session's clock and its stop conditions.
#[derive(Clone, Debug)]
pub struct Budget {
    start: Instant,
    limit: Option<Duration>,
    stop: Option<Arc<AtomicBool>>,
}

impl Budget {
    /// Starts the clock now.
    pub fn new(limit: Option<Duration>, stop: Option<Arc<AtomicBool>>) -> Self {
        Self {
            start: Instant::now(),
            limit,
            stop,
        }
    }

    /// Whether to stop before a step expected to take `next`: a stop was requested, or the
    /// step would end past the budget.
    pub fn should_stop(&self, next: Duration) -> Option<StopReason> {
        if self.stop.as_ref().is_some_and(|s| s.load(Ordering::SeqCst)) {
            return Some(StopReason::Signal);
        }
        match self.limit {
            Some(limit) if self.start.elapsed() + next >= limit => Some(StopReason::TimeBudget),
            _ => None,
        }
    }
}

/// Parses a duration written as hours, minutes and seconds, each an integer with its unit, in
/// that order, e.g. `2h30m`, `90m`, `45s`, `1h5m30s`.
pub fn parse_duration(text: &str) -> Result<Duration> {
    let bad = |why: &str| {
        Error::invalid(
            "--time-budget",
            format!(
                "{why} in {text:?}: expected hours, minutes and seconds such as 2h30m, 90m or 45s"
            ),
        )
    };
    let mut total = 0u64;
    let mut digits = String::new();
    let mut last_unit = 0usize;
    for c in text.trim().chars() {
        if c.is_ascii_digit() {
            digits.push(c);
            continue;
        }
        let (rank, seconds) = match c {
            'h' => (1, 3600),
            'm' => (2, 60),
            's' => (3, 1),
            _ => return Err(bad(&format!("unknown unit {c:?}"))),
        };
        if digits.is_empty() {
            return Err(bad(&format!("no number before {c:?}")));
        }
        if rank <= last_unit {
            return Err(bad("units out of order or repeated"));
        }
        let n: u64 = digits.parse().map_err(|_| bad("number too large"))?;
        total = n
            .checked_mul(seconds)
            .and_then(|v| total.checked_add(v))
            .ok_or_else(|| bad("duration too large"))?;
        digits.clear();
        last_unit = rank;
    }
    if !digits.is_empty() {
        return Err(bad("a number without its unit"));
    }
    if total == 0 {
        return Err(bad("a duration of zero"));
    }
    Ok(Duration::from_secs(total))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_read_as_written_and_bad_ones_are_named() {
        let s = |t: &str| parse_duration(t).map(|d| d.as_secs());
        assert_eq!(s("2h30m").unwrap(), 9000);
        assert_eq!(s("90m").unwrap(), 5400);
        assert_eq!(s("45s").unwrap(), 45);
        assert_eq!(s("1h5m30s").unwrap(), 3930);
        for bad in ["", "30", "m", "5x", "30m2h", "1h1h", "0m", "-5m", "1.5h"] {
            let err = parse_duration(bad).unwrap_err().to_string();
            assert!(err.contains("--time-budget"), "{bad}: {err}");
        }
    }

    #[test]
    fn a_request_or_a_spent_budget_stops_the_session() {
        let none = Budget::new(None, None);
        assert_eq!(none.should_stop(Duration::from_secs(1 << 30)), None);
        let tight = Budget::new(Some(Duration::from_secs(60)), None);
        assert_eq!(tight.should_stop(Duration::from_secs(1)), None);
        assert_eq!(
            tight.should_stop(Duration::from_secs(61)),
            Some(StopReason::TimeBudget)
        );
        let flag = Arc::new(AtomicBool::new(false));
        let asked = Budget::new(None, Some(flag.clone()));
        assert_eq!(asked.should_stop(Duration::ZERO), None);
        flag.store(true, Ordering::SeqCst);
        assert_eq!(asked.should_stop(Duration::ZERO), Some(StopReason::Signal));
    }
}
