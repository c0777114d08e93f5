//! Detection that does not believe every blob (Note S13's region of interest): the
//! background's global motion is fitted and subtracted, the magnitude threshold (raised to the
//! frame's robust noise floor) cuts regions, and each region must pass the photometric test
//! (warping frame 2 with its flow explains the change better than the background's motion)
//! before it reaches the tracker. Every region is kept with its verdict and the reason, for the
//! debug output (`regions.jsonl`).

use serde::{Deserialize, Serialize};

use super::background::{BackgroundModel, GlobalMotion, fit};
use super::photometric::GreyPair;
use super::roi::{Region, regions_of};
use super::run::noise_floor;
use crate::error::{Error, Result};
use crate::types::Flow;

/// Detection settings beyond the magnitude threshold.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DetectConfig {
    /// The background's global motion, fitted and subtracted before the threshold.
    pub background: BackgroundModel,
    /// Pixels sampled (on a regular grid) for the background fit.
    pub background_samples: usize,
    /// The photometric test: on when frames are given.
    pub photometric: bool,
    /// A region passes when (residual with its flow) / (residual with the background's
    /// motion) is at most this.
    pub max_residual_ratio: f64,
    /// Below this residual with the background's motion (grey levels in [0, 1]), nothing in
    /// the region changed between the frames: the region fails the test.
    pub min_change: f64,
}

impl Default for DetectConfig {
    fn default() -> Self {
        Self {
            background: BackgroundModel::Affine,
            background_samples: 4096,
            photometric: true,
            max_residual_ratio: 0.8,
            min_change: 1e-4,
        }
    }
}

impl DetectConfig {
    pub fn validate(&self) -> Result<()> {
        if !(self.max_residual_ratio.is_finite() && self.max_residual_ratio > 0.0) {
            return Err(Error::invalid(
                "detect.max_residual_ratio",
                format!("must be finite and > 0, got {}", self.max_residual_ratio),
            ));
        }
        if !(self.min_change.is_finite() && self.min_change >= 0.0) {
            return Err(Error::invalid(
                "detect.min_change",
                format!("must be finite and >= 0, got {}", self.min_change),
            ));
        }
        if self.background_samples < 16 || self.background_samples > 100_000_000 {
            return Err(Error::invalid(
                "detect.background_samples",
                format!("must be 16..=1e8, got {}", self.background_samples),
            ));
        }
        Ok(())
    }
}

/// One region and what the detector made of it.
#[derive(Clone, Debug, PartialEq)]
pub struct Candidate {
    pub region: Region,
    /// Mean warp residuals (with the region's flow, with the background's motion), when the
    /// photometric test ran.
    pub residuals: Option<(f64, f64)>,
    pub accepted: bool,
    pub reason: String,
}

impl Candidate {
    /// Residual with the flow over residual with the background's motion.
    pub fn ratio(&self) -> Option<f64> {
        self.residuals
            .map(|(f, n)| if n > 0.0 { f / n } else { f64::INFINITY })
    }
}

/// One frame's detection.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameDetection {
    pub background: GlobalMotion,
    /// The magnitude threshold used (px/frame, relative to the background).
    pub threshold: f64,
    pub candidates: Vec<Candidate>,
}

impl FrameDetection {
    /// The accepted regions, largest first.
    pub fn accepted(&self) -> Vec<Region> {
        self.candidates
            .iter()
            .filter(|c| c.accepted)
            .map(|c| c.region.clone())
            .collect()
    }
}

/// Detects the moving regions of `flow` (frame n → n + 1); `frames` (n and n + 1) enable the
/// photometric test. `threshold`, `noise_k` and `min_area` are the magnitude test's settings.
pub fn detect(
    flow: &Flow,
    frames: Option<&GreyPair>,
    threshold: f64,
    noise_k: f64,
    min_area: usize,
    cfg: &DetectConfig,
) -> Result<FrameDetection> {
    let background = fit(flow, cfg.background, cfg.background_samples);
    let relative = if cfg.background == BackgroundModel::None {
        None
    } else {
        Some(background.subtract(flow))
    };
    let test = relative.as_ref().unwrap_or(flow);
    let threshold = threshold.max(noise_floor(test, noise_k));
    let found = regions_of(test, flow, threshold, min_area)?;
    let candidates = found
        .into_iter()
        .map(|(region, pixels)| {
            let photometric = frames.filter(|_| cfg.photometric);
            let residuals = photometric.and_then(|p| p.residuals(&pixels, flow, &background));
            let (accepted, reason) = match (photometric, residuals) {
                (None, _) => (true, "magnitude (no photometric test)".to_string()),
                (Some(_), None) => (
                    false,
                    "photometric: no pixel of the region can be warped".to_string(),
                ),
                (Some(_), Some((_, rn))) if rn < cfg.min_change => (
                    false,
                    format!(
                        "photometric: nothing changed (residual {rn:.2e} < {:.1e})",
                        cfg.min_change
                    ),
                ),
                (Some(_), Some((rf, rn))) => {
                    let r = rf / rn;
                    if r <= cfg.max_residual_ratio {
                        (
                            true,
                            format!("photometric: ratio {r:.2} <= {:.2}", cfg.max_residual_ratio),
                        )
                    } else {
                        (
                            false,
                            format!("photometric: ratio {r:.2} > {:.2}", cfg.max_residual_ratio),
                        )
                    }
                }
            };
            Candidate {
                region,
                residuals,
                accepted,
                reason,
            }
        })
        .collect();
    Ok(FrameDetection {
        background,
        threshold,
        candidates,
    })
}
