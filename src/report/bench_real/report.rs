//! The real-data benchmark's report (`report.json`): for each set and camera the scores of every
//! method over the set and over each pair, the sets that were skipped and why, and a summary
//! per camera that weighs every set the same.

use serde::{Deserialize, Serialize};

use crate::flow::metrics::EpeBySpeed;

/// One method's scores over a set or one pair. `iters` is set for MMS rows only.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MethodScores {
    pub method: String,
    pub iters: Option<usize>,
    pub epe: f64,
    pub ae_deg: f64,
    pub px1: f64,
    pub px3: f64,
    pub px5: f64,
    /// Milliseconds per pair (over a set), or this pair's milliseconds.
    pub ms_per_pair: f64,
    /// The EPE by ground-truth speed (Sintel's s0-10, s10-40, s40+; absent in older reports).
    #[serde(default)]
    pub by_speed: EpeBySpeed,
}

impl MethodScores {
    /// "mms-small, 12 it" or the method's name.
    pub fn label(&self) -> String {
        match self.iters {
            Some(n) => format!("{}, {n} it", self.method),
            None => self.method.clone(),
        }
    }
}

/// One pair of a set: `name` in the generated folder, `source` in the original dataset.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PairResult {
    pub name: String,
    pub source: String,
    pub width: usize,
    pub height: usize,
    /// Pixels with known ground truth.
    pub pixels: u64,
    /// Mean ground-truth speed over them (px), which is also the zero-flow EPE.
    pub mean_gt: f64,
    pub methods: Vec<MethodScores>,
}

/// One set through one camera.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SetRun {
    pub set: String,
    pub camera: String,
    /// The generated dataset folder that was scored.
    pub data: String,
    pub pairs: usize,
    pub pixels: u64,
    pub mean_gt: f64,
    /// Scores over the set: sums over all its known pixels divided by their count.
    pub methods: Vec<MethodScores>,
    pub per_pair: Vec<PairResult>,
}

/// A set that was not run, and why.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Skipped {
    pub set: String,
    pub reason: String,
}

/// Which peer methods ran.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PeersInfo {
    pub ran: bool,
    /// Why they did not run.
    pub skipped_because: Option<String>,
    pub opencv: Option<String>,
    /// Set when `opencv` is not the version of `python/requirements-peers.txt`.
    #[serde(default)]
    pub version_warning: Option<String>,
    pub threads: usize,
}

/// One method through one camera over all sets that ran: `scores` are means of the sets' scores
/// (every set weighs the same), `pooled` are over all their known pixels (a set weighs by its
/// pixels); `ms_per_pair` is over all their pairs in both.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SummaryRow {
    pub camera: String,
    pub scores: MethodScores,
    pub pooled: MethodScores,
    pub sets: usize,
    pub pixels: u64,
}

/// `report.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct BenchRealReport {
    pub config: String,
    pub weights: String,
    pub model: String,
    pub parameters: usize,
    /// Where the network starts: `coarse` (its half-resolution flow) or `zero` (RAFT's and
    /// Table S4's start); empty in reports written before it was recorded.
    #[serde(default)]
    pub start: String,
    /// Threads of the MMS inference (rayon).
    pub threads: usize,
    pub iters: Vec<usize>,
    pub cameras: Vec<String>,
    pub peers: PeersInfo,
    pub skipped: Vec<Skipped>,
    pub runs: Vec<SetRun>,
    pub summary: Vec<SummaryRow>,
}

/// The summary rows of `runs`: for each camera (in `cameras` order) and each method label (in
/// the order of the first run), the mean over the runs that have it.
pub fn summarise(cameras: &[String], runs: &[SetRun]) -> Vec<SummaryRow> {
    let mut out = Vec::new();
    for cam in cameras {
        let of_cam: Vec<&SetRun> = runs.iter().filter(|r| &r.camera == cam).collect();
        let Some(first) = of_cam.first() else {
            continue;
        };
        for m in &first.methods {
            let label = m.label();
            let (mut n, mut pairs, mut pixels, mut ms) = (0usize, 0usize, 0u64, 0.0);
            let (mut acc, mut pooled) = ([0.0f64; 5], [0.0f64; 5]);
            let mut speeds = Vec::new();
            for r in &of_cam {
                if let Some(s) = r.methods.iter().find(|s| s.label() == label) {
                    n += 1;
                    speeds.push(&s.by_speed);
                    pairs += r.pairs;
                    pixels += r.pixels;
                    ms += s.ms_per_pair * r.pairs as f64;
                    for ((a, p), v) in acc
                        .iter_mut()
                        .zip(pooled.iter_mut())
                        .zip([s.epe, s.ae_deg, s.px1, s.px3, s.px5])
                    {
                        *a += v;
                        *p += v * r.pixels as f64;
                    }
                }
            }
            let ms = ms / pairs.max(1) as f64;
            let row = |v: [f64; 5], k: f64, by_speed: EpeBySpeed| MethodScores {
                method: m.method.clone(),
                iters: m.iters,
                epe: v[0] / k,
                ae_deg: v[1] / k,
                px1: v[2] / k,
                px3: v[3] / k,
                px5: v[4] / k,
                ms_per_pair: ms,
                by_speed,
            };
            out.push(SummaryRow {
                camera: cam.clone(),
                scores: row(
                    acc,
                    n.max(1) as f64,
                    EpeBySpeed::mean_of(speeds.iter().copied()),
                ),
                pooled: row(
                    pooled,
                    pixels.max(1) as f64,
                    EpeBySpeed::pooled(speeds.iter().copied()),
                ),
                sets: n,
                pixels,
            });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(method: &str, iters: Option<usize>, epe: f64, ms: f64) -> MethodScores {
        MethodScores {
            method: method.into(),
            iters,
            epe,
            ae_deg: 0.0,
            px1: epe / 10.0,
            px3: 0.0,
            px5: 0.0,
            ms_per_pair: ms,
            by_speed: EpeBySpeed {
                pixels: [60, 40, 0],
                epe: [epe / 2.0, 2.0 * epe, 0.0],
            },
        }
    }

    fn run(set: &str, camera: &str, pairs: usize, methods: Vec<MethodScores>) -> SetRun {
        SetRun {
            set: set.into(),
            camera: camera.into(),
            data: String::new(),
            pairs,
            pixels: pairs as u64 * 100,
            mean_gt: 0.0,
            methods,
            per_pair: Vec::new(),
        }
    }

    #[test]
    fn sets_weigh_the_same_and_time_is_per_pair() {
        let runs = vec![
            run(
                "a",
                "clean",
                3,
                vec![row("m", Some(4), 1.0, 10.0), row("z", None, 5.0, 0.0)],
            ),
            run(
                "b",
                "clean",
                1,
                vec![row("m", Some(4), 3.0, 30.0), row("z", None, 7.0, 0.0)],
            ),
            run("a", "cam", 3, vec![row("m", Some(4), 9.0, 1.0)]),
        ];
        let s = summarise(&["clean".into(), "cam".into(), "none".into()], &runs);
        assert_eq!(s.len(), 3);
        assert_eq!((s[0].scores.label().as_str(), s[0].sets), ("m, 4 it", 2));
        assert_eq!(s[0].scores.epe, 2.0);
        assert!((s[0].scores.px1 - 0.2).abs() < 1e-12);
        // (3 × 10 + 1 × 30) / 4 pairs.
        assert_eq!(s[0].scores.ms_per_pair, 15.0);
        // Pooled: 300 pixels at 1.0 and 100 at 3.0.
        assert_eq!((s[0].pooled.epe, s[0].pixels), (1.5, 400));
        assert_eq!(s[0].pooled.ms_per_pair, 15.0);
        // By speed: the mean of the sets' class means, and pooled by the classes' pixels
        // (each set 60 / 40 / 0 pixels); no set has an s40+ pixel, so neither has a score.
        let (mean, pooled) = (s[0].scores.by_speed, s[0].pooled.by_speed);
        assert_eq!(
            (mean.get(0), mean.get(1), mean.get(2)),
            (Some(1.0), Some(4.0), None)
        );
        assert_eq!(pooled.pixels, [120, 80, 0]);
        assert_eq!((pooled.get(0), pooled.get(1)), (Some(1.0), Some(4.0)));
        assert_eq!((s[1].scores.epe, s[1].sets), (6.0, 2));
        assert_eq!((s[2].camera.as_str(), s[2].scores.epe), ("cam", 9.0));
    }
}
