//! Choosing a forecast by its record (Note S13's predictor against the constant-velocity
//! baseline, Table S5's two rows): every candidate's past forecasts are checked against the
//! positions the track then reached, per horizon k, as an exponentially weighted mean squared
//! error (half-life 30 checked frames); at each horizon the first candidate is used until
//! every candidate has been checked about three times there, and afterwards replaced only by
//! one whose error is clearly lower (at most `SWITCH_RATIO` of the first's).
//! On estimated flow neither predictor wins everywhere (the fit on steadily turning paths,
//! the constant velocity where the direction oscillates within the fit's window), and a
//! track's own past says which one its object follows.

use std::collections::VecDeque;

/// Half-life of a forecast's error in checked frames.
const HALF_LIFE: f64 = 30.0;
/// The weight of checks (each 1, decaying) a horizon needs before its record counts.
const WARM: f64 = 3.0;
/// Another candidate replaces the first at a horizon only where its record's mean squared
/// error is at most this fraction of the first's. Close records say nothing: one frame ahead
/// the fit and the constant velocity differ by less than the noise of the centres, and a
/// choice on the lower of the two there made the forecasts worse on 13 of the 44 tracking
/// clips on MMS flow and better on 2; at 0.7, worse on 4 and better on 3, while 30 frames
/// ahead 30 were better and 1 worse (experiments/results/tracking_log.md).
pub const SWITCH_RATIO: f64 = 0.7;

/// A forecast: positions at 1…K frames ahead.
type Path = Vec<(f64, f64)>;

/// The record of several forecasting candidates of one track.
#[derive(Clone, Debug)]
pub struct ForecastScores {
    candidates: usize,
    /// Recent forecasts: (frame, one path per candidate, positions at 1…K frames ahead).
    past: VecDeque<(usize, Vec<Path>)>,
    /// `[candidate][k − 1]`: (weighted sum of squared errors, weight of the checks).
    scores: Vec<Vec<(f64, f64)>>,
}

impl ForecastScores {
    pub fn new(candidates: usize) -> Self {
        Self {
            candidates: candidates.max(1),
            past: VecDeque::new(),
            scores: vec![Vec::new(); candidates.max(1)],
        }
    }

    /// The track was measured at `at` in `frame`: scores every recorded forecast of this
    /// frame (made k frames ago, at horizon k), after the older checks decay.
    pub fn check(&mut self, frame: usize, at: (f64, f64)) {
        if !(at.0.is_finite() && at.1.is_finite()) {
            return;
        }
        let decay = 0.5f64.powf(1.0 / HALF_LIFE);
        for row in &mut self.scores {
            for s in row.iter_mut() {
                *s = (s.0 * decay, s.1 * decay);
            }
        }
        for (made, paths) in &self.past {
            let Some(k) = frame.checked_sub(*made).filter(|&k| k >= 1) else {
                continue;
            };
            for (c, path) in paths.iter().enumerate() {
                let Some(p) = path.get(k - 1) else { continue };
                let row = &mut self.scores[c];
                if row.len() < k {
                    row.resize(k, (0.0, 0.0));
                }
                let e = (p.0 - at.0).powi(2) + (p.1 - at.1).powi(2);
                if e.is_finite() {
                    row[k - 1].0 += e;
                    row[k - 1].1 += 1.0;
                }
            }
        }
    }

    /// The forecast to report: at each horizon, the position of the candidate with the
    /// best record there, where it beats the first candidate's by `SWITCH_RATIO` (the first
    /// candidate otherwise, and where a record is too short).
    pub fn choose(&self, candidates: &[Path]) -> Path {
        let len = candidates.iter().map(Vec::len).min().unwrap_or(0);
        (0..len)
            .map(|k| {
                let mut records = Vec::with_capacity(candidates.len());
                for c in 0..candidates.len().min(self.candidates) {
                    match self.scores[c].get(k) {
                        Some(&(sum, w)) if w >= WARM => records.push(sum / w),
                        _ => return candidates[0][k],
                    }
                }
                let Some((&first, others)) = records.split_first() else {
                    return candidates[0][k];
                };
                let best = others
                    .iter()
                    .enumerate()
                    .filter(|&(_, &m)| m <= SWITCH_RATIO * first)
                    .min_by(|a, b| a.1.total_cmp(b.1))
                    .map_or(0, |(c, _)| c + 1);
                candidates[best][k]
            })
            .collect()
    }

    /// Records this frame's forecasts of every candidate, to be checked as the track goes
    /// on; forecasts that reach no further than `frame` are dropped.
    pub fn record(&mut self, frame: usize, candidates: impl IntoIterator<Item = Path>) {
        let paths: Vec<Path> = candidates.into_iter().take(self.candidates).collect();
        self.past.push_back((frame, paths));
        while let Some((made, paths)) = self.past.front() {
            let reach = paths.iter().map(Vec::len).max().unwrap_or(0);
            if made + reach <= frame {
                self.past.pop_front();
            } else {
                break;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The object moves 2 px a frame along x. Candidate 0 forecasts it 3 px off at every
    /// horizon, candidate 1 exactly: candidate 0 is reported until candidate 1's record is
    /// long enough at a horizon, candidate 1 afterwards; a horizon never checked keeps
    /// candidate 0.
    #[test]
    fn the_candidate_with_the_better_record_wins_per_horizon() {
        let mut s = ForecastScores::new(2);
        let at = |n: usize| (2.0 * n as f64, 0.0);
        let mut chosen = Vec::new();
        for n in 0..40 {
            s.check(n, at(n));
            let right: Vec<_> = (1..=10).map(|k| at(n + k)).collect();
            let off: Vec<_> = right.iter().map(|p| (p.0, p.1 + 3.0)).collect();
            let candidates = [off, right];
            chosen.push(s.choose(&candidates));
            s.record(n, candidates);
        }
        // Early on: the first candidate.
        assert!((chosen[1][0].1 - 3.0).abs() < 1e-12);
        // Late: the exact one at every horizon.
        for (k, p) in chosen[39].iter().enumerate() {
            assert!(p.1.abs() < 1e-12, "horizon {}: {p:?}", k + 1);
        }
        // Longer forecasts than ever checked keep the first candidate.
        let long: Vec<_> = (1..=20).map(|k| (k as f64, 3.0)).collect();
        let exact: Vec<_> = (1..=20).map(|k| (k as f64, 0.0)).collect();
        let p = s.choose(&[long, exact]);
        assert!(
            p[5].1.abs() < 1e-12 && (p[15].1 - 3.0).abs() < 1e-12,
            "{p:?}"
        );
        // Old forecasts are dropped.
        assert!(s.past.len() <= 10);
    }

    /// A challenger whose record is only a little better than the first candidate's does not
    /// replace it; one clearly better does. The object moves 2 px a frame along x; the first
    /// candidate is `off0` px off, the second `off1`.
    #[test]
    fn only_a_clearly_better_record_replaces_the_first_candidate() {
        let chosen = |off0: f64, off1: f64| {
            let mut s = ForecastScores::new(2);
            let at = |n: usize| (2.0 * n as f64, 0.0);
            let mut last = Vec::new();
            for n in 0..40 {
                s.check(n, at(n));
                let path = |off: f64| (1..=5).map(|k| (at(n + k).0, off)).collect::<Vec<_>>();
                let candidates = [path(off0), path(off1)];
                last = s.choose(&candidates);
                s.record(n, candidates);
            }
            last[0].1
        };
        // Squared errors 1 against 0.81 (ratio 0.81 > SWITCH_RATIO): the first stays.
        assert_eq!(chosen(1.0, 0.9), 1.0);
        // 1 against 0.49 (ratio 0.49): the second takes over.
        assert_eq!(chosen(1.0, 0.7), 0.7);
        // A worse challenger never does.
        assert_eq!(chosen(1.0, 2.0), 1.0);
    }

    #[test]
    fn non_finite_positions_and_empty_candidates_are_harmless() {
        let mut s = ForecastScores::new(2);
        s.record(0, [vec![(1.0, 1.0)], vec![(f64::NAN, 0.0)]]);
        s.check(1, (f64::NAN, 0.0));
        s.check(1, (1.0, 1.0));
        assert_eq!(s.choose(&[vec![(1.0, 1.0)], vec![]]), Vec::new());
        assert_eq!(
            s.choose(&[vec![(1.0, 1.0)], vec![(2.0, 2.0)]]),
            vec![(1.0, 1.0)]
        );
    }
}
