//! One set of tracking settings (Notes S13–S15) for `pins track`, `pins live` and the tracking
//! experiments: the flow (for estimated flow), detection, the tracker and its predictor, the
//! horizons. Two profiles, `exact` (a given flow) and `estimated` (MMS on frames), settle what
//! depends on the flow's source; a JSON file names a profile and overrides what it changes.

use std::path::Path;

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::detect::DetectConfig;
use super::motion::mtp::{Method, SAMPLES_PER_ORDER_MEASURED, TREND_REACH_MEASURED};
use super::run::TrackOptions;
use super::tracker::tracker_config::TrackerConfig;
use crate::error::{Error, Result};
use crate::flow::infer::Predictor;
use crate::flow::iters::Iters;
use crate::flow::video::VideoOptions;

/// Where the flow comes from, which settles the settings that depend on it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Profile {
    /// A given flow (`.flo` files, the scene's truth): its regions are the objects.
    Exact,
    /// A flow estimated from the frames (MMS, DIS): the stages that check the flow against the
    /// frames switch on (change test, alignment, placement) and the predictor's samples count
    /// as measured on the frames.
    Estimated,
}

impl std::str::FromStr for Profile {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "exact" => Ok(Self::Exact),
            "estimated" => Ok(Self::Estimated),
            _ => Err(format!("expected exact or estimated, got {s:?}")),
        }
    }
}

/// The width (px) the tracker's MMS runs at by default: the frame is scaled to it, between 1
/// and `MAX_TRACK_SCALE` times its size (twice a 640×480 frame, four times a 320×240 one). A
/// disc textured like its background and 16 px across is two or three cells of the network's
/// 1/8-resolution features at the frame's size, and the shipped weights report a tenth to a
/// half of its motion there; at twice the size three quarters or more (as OpenCV's DIS does).
/// A camera's frames at half the width hold the same scene at half the size, and the same
/// weights at twice such a frame's size report a tenth (`experiments/results/
/// tracking_history.md`, 2026-11-30 and 2026-12-01). The flow's cost grows with the area run.
pub const TRACK_WIDTH: f64 = 1280.0;

/// The most the default scale enlarges a frame (`flow::scale`'s limit).
pub const MAX_TRACK_SCALE: f64 = 4.0;

/// The tracker's default scale for frames `width` px wide (`TRACK_WIDTH`).
pub fn track_scale(width: usize) -> f64 {
    if width == 0 {
        return 1.0;
    }
    (TRACK_WIDTH / width as f64).clamp(1.0, MAX_TRACK_SCALE)
}

/// The flow network's settings, used where the flow is estimated by MMS.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FlowConfig {
    /// A weights file, or built-in: `mms-small-real` (the tracking default), `default` (= the
    /// same), `mms-small` (stage 3, `pins live`'s default).
    pub weights: String,
    /// Refinement iterations: a count, `"auto"` (at most the weights' own, stopping once the
    /// flow settles) or `null`: the weights' own (12 for the built-in ones).
    pub iters: Option<Iters>,
    /// The multiple of the frame size MMS runs at, in (0, 4] (`flow::scale`): the flow is
    /// resampled to the frame, so tracks stay in its pixels. `null` (the default): the
    /// multiple that makes the frame [`TRACK_WIDTH`] px wide, between 1 and 4 (`track_scale`).
    pub scale: Option<f64>,
    /// What follows MMS: `none` (on the tracking clips the refinement pulls a small, dark
    /// mover's flow towards its background), `variational` or a `.json` file of its settings.
    pub refine: String,
    /// Where MMS starts: `zero` (as the tracking clips were measured) or `coarse`.
    pub start: String,
    /// Reuse each frame's feature encoding in the next pair (`flow::video`): the same flow,
    /// two encoder passes per pair instead of three.
    pub reuse: bool,
    /// Start each pair from the previous pair's flow carried forward (`flow::video`) instead
    /// of `start`.
    pub warm_start: bool,
}

impl Default for FlowConfig {
    fn default() -> Self {
        Self {
            weights: crate::flow::infer::TRACK_WEIGHTS.into(),
            iters: None,
            scale: None,
            refine: "none".into(),
            start: "zero".into(),
            reuse: true,
            warm_start: false,
        }
    }
}

impl FlowConfig {
    /// The network on `device`, with its refinement and start.
    pub fn predictor(&self, device: burn::prelude::Device) -> Result<Predictor> {
        Ok(Predictor::load_on(&self.weights, device)?
            .with_refine(&crate::flow::refine::Refine::parse(&self.refine)?)
            .with_coarse_start(crate::flow::infer::parse_start(&self.start)?))
    }

    /// The most iterations to run (the configured ones, or the weights' own) and what carries
    /// from pair to pair of a video.
    pub fn iters_for(&self, p: &Predictor) -> (usize, VideoOptions) {
        let (iters, stop_px) = self
            .iters
            .unwrap_or(Iters::Fixed(p.config.iters))
            .resolve(p.config.iters);
        let video = VideoOptions {
            reuse: self.reuse,
            warm_start: self.warm_start,
            stop_px,
        };
        (iters, video)
    }

    /// The multiple of the frame size MMS runs at for frames `width` px wide: the one set, or
    /// the default's (`track_scale`).
    pub fn scale_for(&self, width: usize) -> f64 {
        self.scale.unwrap_or_else(|| track_scale(width))
    }

    pub fn validate(&self) -> Result<()> {
        if let Some(s) = self.scale {
            crate::flow::scale::check_scale(s).map_err(|_| {
                Error::invalid("flow.scale", format!("must be in (0, 4] or null, got {s}"))
            })?;
        }
        if let Some(n) = self.iters {
            n.check()
                .map_err(|e| Error::invalid("flow.iters", e.to_string()))?;
        }
        crate::flow::infer::parse_start(&self.start).map_err(|_| {
            Error::invalid(
                "flow.start",
                format!("expected \"zero\" or \"coarse\", got {:?}", self.start),
            )
        })?;
        crate::flow::refine::Refine::parse(&self.refine).map_err(|e| {
            Error::invalid(
                "flow.refine",
                format!("expected \"none\", \"variational\" or a .json file: {e}"),
            )
        })?;
        Ok(())
    }
}

/// Everything that decides a tracking result.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrackConfig {
    /// `exact` or `estimated`; `null`: from the input (`pins track`: `--frames` alone is
    /// estimated, `--flows` exact; `pins live`: estimated; an experiment: its `flow`).
    pub profile: Option<Profile>,
    pub flow: FlowConfig,
    /// Flow magnitude (px/frame, relative to the background) above which a pixel moves.
    pub threshold: f64,
    /// Smallest region (pixels) that is an object.
    pub min_area: usize,
    /// The threshold rises to the frame's median magnitude plus this many robust standard
    /// deviations where the change test is off (an estimated flow's jitter); 0 turns it off.
    pub noise_k: f64,
    /// Background model, change test, photometric test, alignment, placement. Its `change`,
    /// `align` and `place.enabled` are `null` by default: the profile's.
    pub detect: DetectConfig,
    /// Association, confirmation, track life, re-identification and the predictor (`mtp`),
    /// whose `method`, `samples_per_order` and `trend_reach` are `null` by default: settled by
    /// whether the samples are measured on the frames (alignment or placement on).
    pub tracker: TrackerConfig,
    /// Prediction horizons in frames.
    pub horizons: Vec<usize>,
}

impl Default for TrackConfig {
    fn default() -> Self {
        Self {
            profile: None,
            flow: FlowConfig::default(),
            threshold: 0.5,
            min_area: 20,
            noise_k: 3.0,
            detect: DetectConfig::default(),
            tracker: TrackerConfig::default(),
            horizons: vec![1, 15, 30],
        }
    }
}

impl TrackConfig {
    /// The complete settings of a profile.
    pub fn profile(p: Profile) -> Self {
        Self::default().resolved(p)
    }

    /// Reads a config file (a profile and the keys it changes), checked; an error names the
    /// file and the key.
    pub fn from_file(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let value: Value =
            serde_json::from_str(&text).map_err(|e| crate::io::in_config(path, e))?;
        let cfg: Self = from_value_named(&value).map_err(|e| crate::io::in_config(path, e))?;
        cfg.validate().map_err(|e| crate::io::in_config(path, e))?;
        Ok(cfg)
    }

    /// The settings with every default that depends on the flow's source settled (the one
    /// place where that happens): the profile (`fallback` where none is named) turns the
    /// change test, the alignment and the placement on for an estimated flow and off for an
    /// exact one; the predictor's method, samples per order and trend reach are then those of
    /// samples measured on the frames (`select`, 5, 1) where the alignment or the placement
    /// runs, the paper's fit (`poly`, 1, 0) otherwise. A value set stays.
    pub fn resolved(&self, fallback: Profile) -> Self {
        let profile = self.profile.unwrap_or(fallback);
        let estimated = profile == Profile::Estimated;
        let mut c = self.clone();
        c.profile = Some(profile);
        let d = &mut c.detect;
        d.change.get_or_insert(estimated);
        d.align.get_or_insert(estimated);
        d.place.enabled.get_or_insert(estimated);
        let measured = d.align == Some(true) || d.place.enabled == Some(true);
        let (method, per_order, reach) = if measured {
            (
                Method::Select,
                SAMPLES_PER_ORDER_MEASURED,
                TREND_REACH_MEASURED,
            )
        } else {
            (Method::Poly, 1, 0.0)
        };
        let m = &mut c.tracker.mtp;
        m.method.get_or_insert(method);
        m.samples_per_order.get_or_insert(per_order);
        m.trend_reach.get_or_insert(reach);
        c
    }

    /// The tracker's predictor overridden by `over` (an object of `mtp` keys, as an
    /// experiment's predictor gives them); `what` names it in errors.
    pub fn with_mtp(&self, over: &serde_json::Map<String, Value>, what: &str) -> Result<Self> {
        let mut v = serde_json::to_value(&self.tracker.mtp)
            .map_err(|e| Error::invalid(what, e.to_string()))?;
        if let Value::Object(m) = &mut v {
            for (k, x) in over {
                m.insert(k.clone(), x.clone());
            }
        }
        let mut c = self.clone();
        c.tracker.mtp = from_value_named(&v).map_err(|e| Error::invalid(what, e))?;
        Ok(c)
    }

    /// Checks every setting, naming the key of the first bad one.
    pub fn validate(&self) -> Result<()> {
        self.flow.validate()?;
        self.unchecked_options(false).validate()
    }

    /// The options of a run (`debug` keeps every frame's regions), settled by `fallback`
    /// where no profile is named, and checked.
    pub fn options(&self, fallback: Profile, debug: bool) -> Result<TrackOptions> {
        let c = self.resolved(fallback);
        c.flow.validate()?;
        let o = c.unchecked_options(debug);
        o.validate()?;
        Ok(o)
    }

    fn unchecked_options(&self, debug: bool) -> TrackOptions {
        TrackOptions {
            tracker: self.tracker.clone(),
            horizons: self.horizons.clone(),
            threshold: self.threshold,
            noise_k: self.noise_k,
            min_area: self.min_area,
            detect: self.detect.clone(),
            debug,
        }
    }
}

/// `value` as a `T` whose every field has a default; on failure the message names the first
/// key (a dotted path) that fails on its own.
pub fn from_value_named<T: DeserializeOwned>(value: &Value) -> std::result::Result<T, String> {
    T::deserialize(value).map_err(|e| {
        match leaves(value)
            .into_iter()
            .find(|(_, alone)| T::deserialize(alone).is_err())
        {
            Some((key, _)) => format!("{key}: {e}"),
            None => e.to_string(),
        }
    })
}

/// Each leaf of a JSON object: its dotted path, and an object holding only it.
fn leaves(value: &Value) -> Vec<(String, Value)> {
    let Value::Object(map) = value else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for (k, v) in map {
        let inner = leaves(v);
        if inner.is_empty() {
            out.push((k.clone(), single(k, v.clone())));
        } else {
            for (path, alone) in inner {
                out.push((format!("{k}.{path}"), single(k, alone)));
            }
        }
    }
    out
}

fn single(k: &str, v: Value) -> Value {
    let mut m = serde_json::Map::new();
    m.insert(k.to_string(), v);
    Value::Object(m)
}

#[cfg(test)]
mod tests;
