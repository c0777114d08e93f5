//! The stream's clock for the tracker on a stream it cannot keep up with
//! (`track::motion::step`): each processed frame's time in the stream's frames, the span of
//! its flow (the stream frames to the next processed frame) and the stream's frame period,
//! which turns velocities per frame into pixels per second.

use std::collections::VecDeque;

use crate::error::Result;
use crate::track::motion::step::Step;

/// Frame-period samples kept for the median.
const PERIODS: usize = 31;

/// One processed frame's place on the stream.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stamp {
    /// The received frame's sequence number: the stream's frames counted by the reader.
    pub seq: u64,
    /// Its time (s): the camera's clock where it gave one, the arrival time otherwise.
    pub time_s: f64,
    /// Whether `time_s` is the camera's clock.
    pub camera: bool,
}

/// The clock between consecutive processed pairs.
#[derive(Clone, Debug, Default)]
pub struct StreamClock {
    /// The next processed frame's time (stream frames).
    t: f64,
    /// Recent seconds per stream frame.
    periods: VecDeque<f64>,
}

impl StreamClock {
    pub fn new() -> Self {
        Self::default()
    }

    /// The step of the pair `a` → `b` (the pair after the last one: `a` is the last `b`).
    /// The span is the stream frames between them: from the camera's clock over the frame
    /// period where both carry it (a frame the camera itself skipped counts), else the
    /// sequence numbers' difference (the frames the reader received). `dt_s` is the pair's
    /// time step in seconds.
    pub fn step(&mut self, a: Stamp, b: Stamp, dt_s: f64) -> Result<Step> {
        let frames = b.seq.saturating_sub(a.seq).max(1) as f64;
        if dt_s.is_finite() && dt_s > 0.0 {
            self.periods.push_back(dt_s / frames);
            while self.periods.len() > PERIODS {
                self.periods.pop_front();
            }
        }
        let span = match self.period() {
            Some(p) if a.camera && b.camera && dt_s > 0.0 => (dt_s / p).max(0.5),
            _ => frames,
        };
        let step = Step::new(self.t, span)?;
        self.t += span;
        Ok(step)
    }

    /// Seconds per stream frame: the median of the recent pairs' time steps over their frame
    /// counts (`None` before the first pair).
    pub fn period(&self) -> Option<f64> {
        if self.periods.is_empty() {
            return None;
        }
        let mut v: Vec<f64> = self.periods.iter().copied().collect();
        v.sort_by(f64::total_cmp);
        Some(v[v.len() / 2])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stamp(seq: u64, time_s: f64, camera: bool) -> Stamp {
        Stamp {
            seq,
            time_s,
            camera,
        }
    }

    #[test]
    fn spans_count_the_stream_frames_between_processed_ones() {
        // Arrival times only: the spans are the sequence numbers' steps, whatever the jitter.
        let mut c = StreamClock::new();
        let seqs = [0u64, 1, 4, 6, 10, 11];
        let mut steps = Vec::new();
        for w in seqs.windows(2) {
            let (a, b) = (w[0], w[1]);
            let jitter = if b % 2 == 0 { 0.013 } else { -0.009 };
            let dt = (b - a) as f64 / 15.0 + jitter;
            steps.push(
                c.step(stamp(a, 0.0, false), stamp(b, dt, false), dt)
                    .unwrap(),
            );
        }
        let spans: Vec<f64> = steps.iter().map(|s| s.span).collect();
        assert_eq!(spans, [1.0, 3.0, 2.0, 4.0, 1.0]);
        let times: Vec<f64> = steps.iter().map(|s| s.t).collect();
        assert_eq!(times, [0.0, 1.0, 4.0, 6.0, 10.0]);
        assert!((c.period().unwrap() - 1.0 / 15.0).abs() < 0.01);
        // The camera's clock: a frame the camera skipped (seq 3 → 4 over two periods) is one
        // more frame of span.
        let mut c = StreamClock::new();
        let times = [
            (0u64, 0.0),
            (1, 1.0 / 15.0),
            (2, 2.0 / 15.0),
            (3, 3.0 / 15.0),
            (4, 5.0 / 15.0),
        ];
        let mut spans = Vec::new();
        for w in times.windows(2) {
            let (a, b) = (w[0], w[1]);
            let s = c
                .step(stamp(a.0, a.1, true), stamp(b.0, b.1, true), b.1 - a.1)
                .unwrap();
            spans.push(s.span);
        }
        assert!((spans[3] - 2.0).abs() < 1e-9, "{spans:?}");
        assert!(spans[..3].iter().all(|s| (s - 1.0).abs() < 1e-9));
    }
}
