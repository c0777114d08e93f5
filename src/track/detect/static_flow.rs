//! The background-flow magnitude: how much motion a flow reports where nothing
//! moves. Over the truly static pixels of a rendered clip (farther than the object's radius
//! plus a margin, for the camera's blur, from every object's centre in both frames of the
//! pair: the exact flow there is zero), the mean and the 99th percentile of |flow|, pooled
//! over all frames. An exact flow scores 0; a detector that thresholds flow magnitude sees the
//! 99th percentile as spurious motion.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::scene::truth::Truth;
use crate::types::Flow;

/// Histogram resolution (px) and range: magnitudes above the range land in the last bin.
const BIN: f64 = 0.005;
const BINS: usize = 20_000;

/// The metric, as reported.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BackgroundFlow {
    /// Mean |flow| over static pixels (px/frame).
    pub mean: f64,
    /// 99th percentile of |flow| over static pixels (px/frame, to 0.005 px).
    pub p99: f64,
    /// Largest |flow| over static pixels.
    pub max: f64,
    /// Static pixels counted, over all frames.
    pub pixels: u64,
    pub frames: usize,
    /// The margin (px) added to each object's radius.
    pub margin: f64,
}

/// Accumulates |flow| over static pixels frame by frame.
pub struct StaticFlow<'a> {
    truth: &'a Truth,
    margin: f64,
    hist: Vec<u64>,
    sum: f64,
    max: f64,
    n: u64,
    frames: usize,
}

impl<'a> StaticFlow<'a> {
    pub fn new(truth: &'a Truth, margin: f64) -> Result<Self> {
        if !(margin.is_finite() && margin >= 0.0) {
            return Err(Error::invalid(
                "static margin",
                format!("must be finite and >= 0 px, got {margin}"),
            ));
        }
        Ok(Self {
            truth,
            margin,
            hist: vec![0; BINS],
            sum: 0.0,
            max: 0.0,
            n: 0,
            frames: 0,
        })
    }

    /// Adds the flow from frame `frame` to `frame + 1` (unknown vectors are skipped).
    pub fn add(&mut self, frame: usize, flow: &Flow) -> Result<()> {
        let t = self.truth;
        if (flow.width(), flow.height()) != (t.width, t.height) {
            return Err(Error::shape(
                format!("flow {frame} against truth.json"),
                format!("{}x{}", t.width, t.height),
                format!("{}x{}", flow.width(), flow.height()),
            ));
        }
        if frame + 1 >= t.frames {
            return Err(Error::invalid(
                "flows",
                format!(
                    "flow {frame} is past the truth's {} frames (flow n is frame n to n + 1)",
                    t.frames
                ),
            ));
        }
        let discs: Vec<(f64, f64, f64)> = t
            .objects
            .iter()
            .flat_map(|o| {
                let r = o.radius + self.margin;
                [o.centroids[frame], o.centroids[frame + 1]].map(|c| (c[0], c[1], r * r))
            })
            .collect();
        let (w, h) = (flow.width(), flow.height());
        let (u, v) = (flow.u(), flow.v());
        for y in 0..h {
            for x in 0..w {
                let (xf, yf) = (x as f64, y as f64);
                if discs
                    .iter()
                    .any(|&(cx, cy, r2)| (xf - cx).powi(2) + (yf - cy).powi(2) <= r2)
                {
                    continue;
                }
                let p = y * w + x;
                let m = (u[p] as f64).hypot(v[p] as f64);
                if !m.is_finite() {
                    continue;
                }
                self.sum += m;
                self.max = self.max.max(m);
                self.n += 1;
                self.hist[((m / BIN) as usize).min(BINS - 1)] += 1;
            }
        }
        self.frames += 1;
        Ok(())
    }

    /// The metric so far; `None` before any static pixel.
    pub fn summary(&self) -> Option<BackgroundFlow> {
        if self.n == 0 {
            return None;
        }
        let target = (0.99 * self.n as f64).ceil() as u64;
        let mut seen = 0u64;
        let mut p99 = self.max;
        for (i, &c) in self.hist.iter().enumerate() {
            seen += c;
            if seen >= target {
                p99 = if i + 1 == BINS {
                    self.max
                } else {
                    ((i + 1) as f64 * BIN).min(self.max)
                };
                break;
            }
        }
        Some(BackgroundFlow {
            mean: self.sum / self.n as f64,
            p99,
            max: self.max,
            pixels: self.n,
            frames: self.frames,
            margin: self.margin,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::truth::TruthObject;

    #[test]
    fn counts_only_static_pixels_and_reads_the_percentile() {
        let truth = Truth {
            width: 40,
            height: 30,
            fps: 30.0,
            frames: 3,
            objects: vec![TruthObject {
                index: 0,
                radius: 4.0,
                centroids: vec![[10.0, 10.0], [14.0, 10.0], [18.0, 10.0]],
                visible: vec![true; 3],
            }],
        };
        let mut f = Flow::zeros(30, 40);
        // The mover (huge flow) is excluded; 1 % of the static pixels carry 2 px.
        for y in 0..30 {
            for x in 0..40 {
                if (x as f64 - 12.0).hypot(y as f64 - 10.0) < 7.0 {
                    f.set(y, x, 50.0, 0.0);
                }
            }
        }
        let mut s = StaticFlow::new(&truth, 2.0).unwrap();
        assert!(s.summary().is_none());
        s.add(0, &f).unwrap();
        let n = s.summary().unwrap().pixels as usize;
        assert!(n < 1200 && n > 1000, "{n}");
        let mut g = Flow::zeros(30, 40);
        let mut k = 0;
        for y in 20..30 {
            for x in 0..40 {
                if k < n / 100 {
                    g.set(y, x, 0.0, 2.0);
                    k += 1;
                }
            }
        }
        let mut s = StaticFlow::new(&truth, 2.0).unwrap();
        s.add(0, &g).unwrap();
        let r = s.summary().unwrap();
        assert!(r.p99 <= 0.005 && r.max == 2.0, "{r:?}");
        assert!((r.mean - 2.0 * k as f64 / n as f64).abs() < 1e-9);
        g.set(29, 39, 0.0, 2.0);
        g.set(29, 38, 0.0, 2.0);
        let mut s = StaticFlow::new(&truth, 2.0).unwrap();
        s.add(1, &g).unwrap();
        assert!((s.summary().unwrap().p99 - 2.0).abs() < 0.006);
        // A flow past the clip, of another size, or a bad margin is an error.
        assert!(s.add(2, &g).is_err());
        assert!(s.add(0, &Flow::zeros(3, 3)).is_err());
        assert!(StaticFlow::new(&truth, f64::NAN).is_err());
    }
}
