//! The detector's settings (Note S13's region of interest and its tests): the background's
//! fit, the thresholds, the change and photometric tests, the alignment, the placement on a
//! still background; each checked by `validate` before a clip is run.

use serde::{Deserialize, Serialize};

use super::align::{ALIGN_WEIGHTS, weights_valid};
use super::background::BackgroundModel;
use super::still_background::{PlaceConfig, StillBackground};
use crate::error::{Error, Result};

/// Detection settings beyond the magnitude threshold.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DetectConfig {
    /// The background's global motion, fitted and subtracted before the threshold.
    pub background: BackgroundModel,
    /// With frames: the change mask and the photometric test compare against the fitted
    /// global motion only where the frames support it (warping by it explains frame 1 better
    /// than no motion, `GreyPair::supports`), and against a still background otherwise. An
    /// estimated flow's global bias on a still scene is not the camera's motion.
    pub check_background: bool,
    /// Pixels sampled (on a regular grid) for the background fit.
    pub background_samples: usize,
    /// The photometric test: on when frames are given.
    pub photometric: bool,
    /// A region passes when (residual with its flow) / (residual with the background's
    /// motion) is at most this.
    pub max_residual_ratio: f64,
    /// Below this residual with the background's motion (grey levels in [0, 1]), nothing in
    /// the region changed between the frames: the region fails the test. Also the least
    /// level of the change test.
    pub min_change: f64,
    /// The change test (it runs when frames are given): a pixel moves only where the frames'
    /// box-averaged difference exceeds their noise floor, and each such seed grows to its
    /// object by the motion the frames confirm; the flow-noise floor (`noise_k`) then does
    /// not raise the magnitude threshold. `null` (the default): on for an estimated flow
    /// (MMS), off for a given one (`TrackConfig::resolved`, by the profile).
    pub change: Option<bool>,
    /// Side of the box (pixels, odd) that averages the frames' difference.
    pub change_window: usize,
    /// The change test's noise floor: the median plus this many robust standard deviations
    /// of the averaged difference.
    pub change_k: f64,
    /// A seed grows inside its box widened by its motion plus this many pixels ...
    pub grow_margin: usize,
    /// ... and only through pixels within this distance of a changed pixel, so it does not
    /// annex the spurious flow of the still background around it.
    pub grow_reach: usize,
    /// With the change test: each grown region loses the pixels whose 5×5 neighbourhood the
    /// background's motion explains better than the region's motion, by more than the change
    /// test's level (the halo an estimated flow leaves around a mover; `track::detect::trim`).
    pub trim: bool,
    /// With frames: each accepted region's motion is the translation that best maps its
    /// colours in frame n onto frame n + 1 (`track::detect::align`, searched around its mean flow),
    /// where that explains the frames better than the mean flow: the trajectory fits' speed
    /// and direction samples (`Region::aligned`). `null` (the default): on for an estimated
    /// flow, off for a given one (`TrackConfig::resolved`, by the profile).
    pub align: Option<bool>,
    /// The alignment searches at most this many pixels from the mean flow on each axis.
    pub align_reach: usize,
    /// The weights of the R, G and B residuals in the alignment (`track::detect::align::ALIGN_WEIGHTS`:
    /// green first, as the metalens PSF is sharp in green and broad in red and blue; `[1, 1, 1]`
    /// for a camera whose channels are equally sharp). Grey frames ignore them.
    pub align_weights: [f64; 3],
    /// With the alignment on: a region that fails the photometric test with its flow is
    /// retried with its aligned motion and, where that passes, accepted as a weak detection
    /// that continues a confirmed track but starts none (`track::detect::retry`).
    pub retry_aligned: bool,
    /// With frames and a still camera: each accepted region's centroid moves to its object in
    /// the frame (where it differs from the temporal median of the last frames;
    /// `track::detect::still_background`).
    pub place: PlaceConfig,
}

impl Default for DetectConfig {
    fn default() -> Self {
        Self {
            background: BackgroundModel::Affine,
            check_background: true,
            background_samples: 4096,
            photometric: true,
            max_residual_ratio: 0.8,
            min_change: 1e-4,
            change: None,
            change_window: 7,
            change_k: 4.0,
            grow_margin: 24,
            grow_reach: 10,
            trim: true,
            align: None,
            align_reach: 24,
            align_weights: ALIGN_WEIGHTS,
            retry_aligned: true,
            place: PlaceConfig::default(),
        }
    }
}

impl DetectConfig {
    /// The still background of a run when the placement is on (its `null` default counts as
    /// on: `TrackConfig::resolved` settles it by the profile).
    pub fn still_background(&self) -> Result<Option<StillBackground>> {
        if self.place.enabled == Some(false) {
            return Ok(None);
        }
        StillBackground::new(self.place.clone()).map(Some)
    }

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
        if self.change_window.is_multiple_of(2) || self.change_window > 101 {
            return Err(Error::invalid(
                "detect.change_window",
                format!("must be odd and at most 101, got {}", self.change_window),
            ));
        }
        if !(self.change_k.is_finite() && self.change_k >= 0.0) {
            return Err(Error::invalid(
                "detect.change_k",
                format!("must be finite and >= 0, got {}", self.change_k),
            ));
        }
        if self.grow_reach > 1000 {
            return Err(Error::invalid(
                "detect.grow_reach",
                format!("must be at most 1000 px, got {}", self.grow_reach),
            ));
        }
        if self.grow_margin > 1000 {
            return Err(Error::invalid(
                "detect.grow_margin",
                format!("must be at most 1000 px, got {}", self.grow_margin),
            ));
        }
        if !(1..=256).contains(&self.align_reach) {
            return Err(Error::invalid(
                "detect.align_reach",
                format!("must be 1..=256 px, got {}", self.align_reach),
            ));
        }
        if !weights_valid(&self.align_weights) {
            return Err(Error::invalid(
                "detect.align_weights",
                format!(
                    "must be three finite weights >= 0, not all 0, got {:?}",
                    self.align_weights
                ),
            ));
        }
        if self.background_samples < 16 || self.background_samples > 100_000_000 {
            return Err(Error::invalid(
                "detect.background_samples",
                format!("must be 16..=1e8, got {}", self.background_samples),
            ));
        }
        self.place.validate()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_change_settings_are_refused() {
        for cfg in [
            DetectConfig {
                change_window: 6,
                ..DetectConfig::default()
            },
            DetectConfig {
                change_k: f64::NAN,
                ..DetectConfig::default()
            },
            DetectConfig {
                grow_margin: 5000,
                ..DetectConfig::default()
            },
        ] {
            assert!(cfg.validate().is_err(), "{cfg:?}");
        }
    }
}
