//! The time of one tracked frame (Note S13's frame index, generalised): on a stream processed
//! at uneven gaps, the processed frame's time in the stream's frames and the span of its flow
//! (the stream frames to the next processed frame). At the full rate both are whole: frame n,
//! span 1.

use crate::error::{Error, Result};

/// One processed frame's place on the stream's time axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Step {
    /// Its time, in the stream's frames.
    pub t: f64,
    /// The stream frames its flow spans: the time to the next processed frame (> 0).
    pub span: f64,
}

impl Step {
    /// Frame `n` of a stream processed at its full rate.
    pub fn every(n: usize) -> Self {
        Self {
            t: n as f64,
            span: 1.0,
        }
    }

    /// A processed frame at time `t` whose flow spans `span` stream frames.
    pub fn new(t: f64, span: f64) -> Result<Self> {
        if !(t.is_finite() && t >= 0.0 && span.is_finite() && span > 0.0) {
            return Err(Error::invalid(
                "tracking step",
                format!("time must be finite and >= 0 and span finite and > 0, got {t} and {span}"),
            ));
        }
        Ok(Self { t, span })
    }

    /// The stream frame it is (its time, rounded): the index of histories and records.
    pub fn frame(&self) -> usize {
        self.t.round() as usize
    }
}

/// A point of a path sampled at 1, 2, … frames after `start`, at `s` ≥ 0 frames (linear
/// between the samples, the last two's line past them); exactly the k-th sample at whole `s`.
pub fn along(start: (f64, f64), path: &[(f64, f64)], s: f64) -> (f64, f64) {
    let point = |k: usize| if k == 0 { start } else { path[k - 1] };
    if path.is_empty() || s <= 0.0 {
        return start;
    }
    if s.fract() == 0.0 && s as usize <= path.len() {
        return point(s as usize);
    }
    let k = (s.floor() as usize).min(path.len() - 1);
    let frac = s - k as f64;
    let (a, b) = (point(k), point(k + 1));
    (a.0 + (b.0 - a.0) * frac, a.1 + (b.1 - a.1) * frac)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_are_checked_and_paths_read_between_their_samples() {
        assert_eq!(Step::every(7), Step::new(7.0, 1.0).unwrap());
        assert_eq!(Step::new(6.6, 2.5).unwrap().frame(), 7);
        for (t, s) in [
            (-1.0, 1.0),
            (1.0, 0.0),
            (f64::NAN, 1.0),
            (1.0, f64::INFINITY),
        ] {
            let e = Step::new(t, s).unwrap_err().to_string();
            assert!(e.contains("tracking step"), "{e}");
        }
        let path = [(1.0, 0.0), (2.0, 0.0), (4.0, 2.0)];
        assert_eq!(along((0.0, 0.0), &path, 0.0), (0.0, 0.0));
        assert_eq!(along((0.0, 0.0), &path, 1.0), (1.0, 0.0));
        assert_eq!(along((0.0, 0.0), &path, 2.5), (3.0, 1.0));
        assert_eq!(along((0.0, 0.0), &path, 3.0), (4.0, 2.0));
        // Past the samples: on along the last segment's line.
        assert_eq!(along((0.0, 0.0), &path, 4.0), (6.0, 4.0));
        assert_eq!(along((5.0, 5.0), &[], 2.0), (5.0, 5.0));
    }
}
