//! The multi-object tracker's settings (Note S13's many objects, Movie S2): gates,
//! confirmation, patience, fragments, appearance and re-identification, with their defaults.
//! Association (`track::tracker::associate`) and the tracker's frame step (`track::tracker::multi`) read them.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::track::motion::mtp::MtpConfig;

/// Tracker settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrackerConfig {
    pub mtp: MtpConfig,
    /// Largest distance (px) between a prediction and a detection that may be matched; it
    /// widens by half for every frame a track has coasted, so a track re-acquires its object
    /// after an occlusion or a merge. A small object's gate is narrower: at most
    /// `associate::GATE_RADII` of its radius.
    pub gate_px: f64,
    /// Consecutive hits before a new track is reported (the confirmation window).
    pub confirm: usize,
    /// Misses before a track ends.
    pub patience: usize,
    /// Misses a tentative track survives (k of n confirmation): it coasts on its prediction
    /// and is confirmed after `confirm` hits with at most this many misses in a row between
    /// them, its consistency window bridging each gap with its last hit's motion. 0: the
    /// hits must be consecutive (SORT's and DeepSORT's rule).
    pub tentative_patience: usize,
    /// Motion consistency over the confirmation window: the centre's displacement from the
    /// first to the last hit must match the sum of the regions' motions (the aligned motion
    /// where the frames confirmed it, the mean flow otherwise; the centre the placed one where
    /// there is one) within `consistency_px + consistency_rel × |sum|`. Infinite turns the
    /// test off.
    pub consistency_px: f64,
    pub consistency_rel: f64,
    /// An estimated flow may underestimate a small mover (it smooths the object into its
    /// background): above 1, a centre that moved further than the flows say, in their
    /// direction (within 30°), is consistent up to this many times their sum. A spurious
    /// blob, which stays where it is while its flow says it moves, still fails. 1 (the
    /// default) asks the flow to be right within the tolerance above.
    pub consistency_max_ratio: f64,
    /// The gate widens by half per coasted frame up to this many times `gate_px`.
    pub max_gate_factor: f64,
    /// Motion gate: a detection whose mean flow differs from the track's velocity by more
    /// than `velocity_gate_px + velocity_gate_rel × |velocity|` (px/frame) is not matched to
    /// it (a spurious blob beside a coasting track moves its own way). Infinite turns it off.
    pub velocity_gate_px: f64,
    pub velocity_gate_rel: f64,
    /// No track is born from a detection within this distance (px) of a confirmed track's
    /// centre: a second region on the same object (a fragment of a poorly estimated flow) is
    /// not a second object.
    pub birth_exclusion_px: f64,
    /// A matched detection smaller than this fraction of the track's median area over its
    /// last `area_window` observations is a fragment of the object (part of it moves in an
    /// estimated flow): it keeps the track alive, but its centre, which can lie anywhere on
    /// the object, does not move the track, which coasts through that frame. A region placed
    /// on the frame (`Region::placed`) is never a fragment. 0 turns it off.
    pub partial_area_ratio: f64,
    pub area_window: usize,
    /// A track that has coasted (no detection) for more than this many consecutive frames is
    /// kept, to take its object back within `patience`, but not reported: its estimate is an
    /// extrapolation that no measurement has checked for that long (SORT reports matched
    /// tracks only, i.e. 0 here).
    pub max_coast_reported: usize,
    /// The appearance cue (`track::tracker::appearance`, with frames): a detection whose colour lies
    /// more than `appearance_k` standard deviations from a track's running colour (each
    /// channel's at least `appearance_floor` 8-bit levels) is not matched to it, and each
    /// standard deviation adds `appearance_px` to the matching cost (px), so where two objects
    /// meet, each track prefers its own. Infinite `appearance_k` and 0 `appearance_px` turn it
    /// off.
    pub appearance_k: f64,
    pub appearance_floor: f64,
    pub appearance_px: f64,
    /// A matched region that the still background could not place because the foreground's
    /// centre lay too far from its flow centroid (`Region::foreground`) is placed there after
    /// all when that centre lies nearer the track's prediction than the flow centroid does,
    /// and within this share of the region's equivalent radius of the prediction: the motion
    /// model, not the smeared flow, vouches for it. 0 turns it off.
    pub foreground_gate: f64,
    /// Matching cascade (DeepSORT's): the confirmed tracks are matched in order of recency
    /// (those seen in the last frame first, then those missed once, …), the tentative ones
    /// last, each to the detections the earlier ones left. Without it, one assignment over all
    /// tracks maximises the number of matches, so a tentative track born on a fragment can
    /// push a confirmed track onto a farther detection, and a track that has coasted, its gate
    /// widened, can take the object of one seen a frame ago.
    pub match_cascade: bool,
    /// Re-identification: a confirmed track that ended (its patience spent, or it coasted out
    /// of the view) is remembered for this many frames after it was last seen; 0 turns
    /// re-identification off.
    pub reid_frames: usize,
    /// A track being confirmed takes the ID of an ended (or a coasting) track when it was born
    /// after that track was last seen, within `gate_px` + 1.25 × the track's top speed × the
    /// frames between (`reid::REACH_SPEED_FACTOR`), and its mean colour lies within this many
    /// of the old track's standard deviations (`appearance_floor` at least); of several, the
    /// one of least cost, colour distance over `reid_k` plus distance over reach
    /// (`reid::reid_cost`). Both need colours (frames).
    pub reid_k: f64,
    /// A weak detection (`track::detect::retry`: a region that passed the photometric test only with
    /// the motion the frames confirm) may continue a tentative track, one that a detection
    /// which passed with its flow started, as well as a confirmed one; either way it starts
    /// none. Off, only confirmed tracks take weak detections (ByteTrack's second association):
    /// a disc textured like its background, whose flow passes the test now and then, starts
    /// tentative tracks that die at its first weak frame and is never confirmed.
    pub weak_continues_tentative: bool,
}

impl Default for TrackerConfig {
    fn default() -> Self {
        Self {
            mtp: MtpConfig::default(),
            gate_px: 40.0,
            confirm: 5,
            patience: 15,
            tentative_patience: 0,
            consistency_px: 2.0,
            consistency_rel: 0.3,
            consistency_max_ratio: 1.0,
            max_gate_factor: 2.0,
            velocity_gate_px: 2.0,
            velocity_gate_rel: 0.5,
            birth_exclusion_px: 30.0,
            partial_area_ratio: 0.35,
            area_window: 15,
            max_coast_reported: 0,
            appearance_k: 6.0,
            appearance_floor: 8.0,
            appearance_px: 5.0,
            foreground_gate: 0.5,
            match_cascade: true,
            reid_frames: 150,
            reid_k: 3.0,
            weak_continues_tentative: true,
        }
    }
}

impl TrackerConfig {
    /// Checks every setting, naming the key of the first bad one.
    pub fn validate(&self) -> Result<()> {
        self.mtp.validate()?;
        if !(self.gate_px.is_finite() && self.gate_px > 0.0) {
            return Err(Error::invalid(
                "tracker.gate_px",
                format!("must be finite and > 0, got {}", self.gate_px),
            ));
        }
        if self.confirm == 0 {
            return Err(Error::invalid("tracker.confirm", "must be >= 1, got 0"));
        }
        if self.tentative_patience > self.patience {
            return Err(Error::invalid(
                "tracker.tentative_patience",
                format!(
                    "must be <= tracker.patience ({}), got {}",
                    self.patience, self.tentative_patience
                ),
            ));
        }
        if !(0.0..1.0).contains(&self.partial_area_ratio) {
            return Err(Error::invalid(
                "tracker.partial_area_ratio",
                format!("must be in [0, 1), got {}", self.partial_area_ratio),
            ));
        }
        if self.consistency_max_ratio.is_nan() || self.consistency_max_ratio < 1.0 {
            return Err(Error::invalid(
                "tracker.consistency_max_ratio",
                format!("must be >= 1, got {}", self.consistency_max_ratio),
            ));
        }
        if !(self.foreground_gate.is_finite() && self.foreground_gate >= 0.0) {
            return Err(Error::invalid(
                "tracker.foreground_gate",
                format!(
                    "must be finite and >= 0 (0: off), got {}",
                    self.foreground_gate
                ),
            ));
        }
        if self.max_gate_factor.is_nan() || self.max_gate_factor < 1.0 {
            return Err(Error::invalid(
                "tracker.max_gate_factor",
                format!("must be >= 1, got {}", self.max_gate_factor),
            ));
        }
        for (n, v) in [
            ("consistency_px", self.consistency_px),
            ("consistency_rel", self.consistency_rel),
            ("velocity_gate_px", self.velocity_gate_px),
            ("velocity_gate_rel", self.velocity_gate_rel),
            ("birth_exclusion_px", self.birth_exclusion_px),
            ("appearance_k", self.appearance_k),
            ("reid_k", self.reid_k),
        ] {
            if v.is_nan() || v < 0.0 {
                return Err(Error::invalid(
                    format!("tracker.{n}"),
                    format!("must be >= 0 (inf turns the test off), got {v}"),
                ));
            }
        }
        if !(self.appearance_floor.is_finite() && self.appearance_floor > 0.0) {
            return Err(Error::invalid(
                "tracker.appearance_floor",
                format!("must be finite and > 0, got {}", self.appearance_floor),
            ));
        }
        if !(self.appearance_px.is_finite() && self.appearance_px >= 0.0) {
            return Err(Error::invalid(
                "tracker.appearance_px",
                format!("must be finite and >= 0, got {}", self.appearance_px),
            ));
        }
        Ok(())
    }
}
