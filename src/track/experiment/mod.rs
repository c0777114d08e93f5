//! Tracking experiments (Table S5, Note S14): several clips × several predictors, each clip
//! tracked from its exact flow or from MMS flow on its camera frames, every track scored at
//! every horizon, with the run time per frame: one table a reader can compare across.

use std::path::Path;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::config::{Profile, TrackConfig, from_value_named};
use super::detect::photometric::{GreyFrame, GreyPair};
use super::eval::evaluate;
pub use super::eval::points::{OperatingPoint, PointRow, points_chart, points_table};
use super::run::{FlowStep, TrackOptions, track_sequence};
use super::tracker::tracks::Tracks;
use crate::dataset::sequence::SequenceConfig;
use crate::error::{Error, Result};
use crate::flow::infer::Predictor;
use crate::flow::sequence::pair_flows_scaled;
use crate::flow::video::VideoOptions;
use crate::rng;
use crate::scene::truth::Truth;
use crate::types::Flow;

/// Where the flow maps come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FlowSource {
    /// The scene's exact flow: isolates the predictor's error.
    Truth,
    /// MMS on the camera frames: the whole system, as in the paper.
    Mms,
    /// OpenCV's DIS (medium) on the same camera frames, through Python (`flow::dis`): the peer.
    Dis,
}

/// One named clip: a clip file, or the clip written in the experiment, rendered once or once per
/// seed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClipSpec {
    pub name: String,
    /// A clip file (`scene` and `camera`, as `pins track render` takes), relative to the
    /// experiment file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub config: Option<std::path::PathBuf>,
    /// Or the clip itself, written here as in a clip file.
    #[serde(default, rename = "clip", skip_serializing_if = "Option::is_none")]
    pub inline: Option<SequenceConfig>,
    /// Render the clip once per seed (the scene's seed replaced), each run named `NAME_seedN`;
    /// empty: once, with the clip's own seed.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub seeds: Vec<u64>,
    /// The loaded clip (filled in by `ExperimentConfig::from_file`, one spec per seed).
    #[serde(skip)]
    pub loaded: SequenceConfig,
}

impl ClipSpec {
    /// The clip's runs: its file or inline clip loaded (paths relative to `base`), once per seed.
    pub fn expand(self, base: &Path) -> Result<Vec<ClipSpec>> {
        let what = format!("clip {:?}", self.name);
        let clip = match (&self.config, &self.inline) {
            (Some(file), None) => SequenceConfig::from_file(&base.join(file))?,
            (None, Some(inline)) => {
                let mut clip = inline.clone();
                clip.camera.resolve_paths(base);
                clip.validate()
                    .map_err(|e| Error::invalid(&what, e.to_string()))?;
                clip
            }
            _ => {
                return Err(Error::invalid(
                    &what,
                    "needs either \"config\" (a clip file) or \"clip\" (the clip itself)",
                ));
            }
        };
        let one = |name: String, clip: SequenceConfig| ClipSpec {
            name,
            config: self.config.as_ref().map(|f| base.join(f)),
            inline: None,
            seeds: Vec::new(),
            loaded: clip,
        };
        if self.seeds.is_empty() {
            return Ok(vec![one(self.name.clone(), clip)]);
        }
        let mut seen = std::collections::BTreeSet::new();
        self.seeds
            .iter()
            .map(|&seed| {
                if !seen.insert(seed) {
                    return Err(Error::invalid(
                        &what,
                        format!("seed {seed} is listed twice"),
                    ));
                }
                let mut c = clip.clone();
                c.scene.seed = seed;
                Ok(one(format!("{}_seed{seed}", self.name), c))
            })
            .collect()
    }
}

/// One named predictor setting: `mtp` keys that override the experiment's `track.tracker.mtp`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PredictorSpec {
    pub name: String,
    #[serde(default)]
    pub mtp: serde_json::Map<String, serde_json::Value>,
}

/// An experiment file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExperimentConfig {
    pub clips: Vec<ClipSpec>,
    pub predictors: Vec<PredictorSpec>,
    /// Prediction horizons (frames); they replace `track.horizons`.
    pub horizons: Vec<usize>,
    #[serde(default = "default_source")]
    pub flow: FlowSource,
    /// The tracking settings (`TrackConfig`): the profile follows `flow` (`truth`: exact,
    /// `mms` and `dis`: estimated) unless the file names one; `track.flow` is MMS's.
    #[serde(default)]
    pub track: TrackConfig,
    /// MMS flow only: the points of the whole system's error-against-run-time curve (flow
    /// resolution and iterations). Empty: one point, `track.flow.scale` (for each clip's width
    /// where it is `null`) and `track.flow.iters`.
    #[serde(default)]
    pub operating_points: Vec<OperatingPoint>,
}

fn default_source() -> FlowSource {
    FlowSource::Truth
}

impl ExperimentConfig {
    /// The operating points to run on a clip `width` px wide: the configured ones, or
    /// `track.flow`'s scale and iterations (`weights_iters`, the weights' own, where it names
    /// none).
    pub fn points(&self, weights_iters: usize, width: usize) -> Vec<OperatingPoint> {
        if self.operating_points.is_empty() {
            vec![OperatingPoint {
                scale: self.track.flow.scale_for(width),
                iters: self
                    .track
                    .flow
                    .iters
                    .map_or(weights_iters, |n| n.resolve(weights_iters).0),
            }]
        } else {
            self.operating_points.clone()
        }
    }

    /// The profile of the experiment's flow where `track` names none.
    pub fn profile(&self) -> Profile {
        match self.flow {
            FlowSource::Truth => Profile::Exact,
            FlowSource::Mms | FlowSource::Dis => Profile::Estimated,
        }
    }

    /// The run options of predictor number `index`: `track` with its `mtp` keys, settled by
    /// the profile.
    pub fn options(&self, index: usize) -> Result<TrackOptions> {
        let p = self
            .predictors
            .get(index)
            .ok_or_else(|| Error::invalid("predictors", format!("no predictor {index}")))?;
        let mut track = self
            .track
            .with_mtp(&p.mtp, &format!("predictors[{index}].mtp ({})", p.name))?;
        track.horizons = self.horizons.clone();
        track.options(self.profile(), false)
    }

    pub fn from_file(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let value: serde_json::Value =
            serde_json::from_str(&text).map_err(|e| crate::io::in_config(path, e))?;
        // The tracking settings first, so an error names their key.
        if let Some(t) = value.get("track") {
            from_value_named::<TrackConfig>(t)
                .map_err(|e| crate::io::in_config(path, format!("track.{e}")))?;
        }
        let mut cfg: Self =
            serde_json::from_value(value).map_err(|e| crate::io::in_config(path, e))?;
        let base = path.parent().unwrap_or(Path::new(""));
        let specs = std::mem::take(&mut cfg.clips);
        for c in specs {
            let runs = c.expand(base).map_err(|e| crate::io::in_config(path, e))?;
            cfg.clips.extend(runs);
        }
        cfg.validate().map_err(|e| crate::io::in_config(path, e))?;
        Ok(cfg)
    }

    pub fn validate(&self) -> Result<()> {
        if self.clips.is_empty() || self.predictors.is_empty() {
            return Err(Error::invalid(
                "experiment",
                "needs at least one clip and one predictor",
            ));
        }
        if self.horizons.is_empty() || self.horizons.iter().any(|&h| h == 0 || h > 10_000) {
            return Err(Error::invalid("horizons", "need horizons in 1..=10000"));
        }
        self.track
            .validate()
            .map_err(|e| Error::invalid("track", e.to_string()))?;
        // Only the network runs at a scale: another flow refuses one set away from the default.
        if self.track.flow.scale.is_some() && self.flow != FlowSource::Mms {
            return Err(Error::invalid(
                "track.flow.scale",
                "only MMS flow runs at a scale (set \"flow\": \"mms\")",
            ));
        }
        if !self.operating_points.is_empty() && self.flow != FlowSource::Mms {
            return Err(Error::invalid(
                "operating_points",
                "only MMS flow has operating points (set \"flow\": \"mms\")",
            ));
        }
        for p in &self.operating_points {
            crate::flow::scale::check_scale(p.scale)
                .map_err(|e| Error::invalid("operating_points", e.to_string()))?;
            if p.iters == 0 || p.iters > 64 {
                return Err(Error::invalid(
                    "operating_points",
                    format!("iters must be in 1..=64, got {}", p.iters),
                ));
            }
        }
        let mut names = std::collections::BTreeSet::new();
        for c in &self.clips {
            if !names.insert(c.name.as_str()) {
                return Err(Error::invalid(
                    "clips",
                    format!("two clips are named {:?}", c.name),
                ));
            }
            c.loaded.validate()?;
        }
        for i in 0..self.predictors.len() {
            self.options(i)?;
        }
        Ok(())
    }
}

/// A clip's flows and truth, computed once and shared by every predictor.
pub struct ClipData {
    pub truth: Truth,
    pub flows: Vec<Flow>,
    /// The camera frames (MMS clips), for the photometric test.
    pub frames: Option<Vec<GreyFrame>>,
}

/// The flows of a clip: exact, or MMS on its camera frames (`predictor` must then be given),
/// carrying `video` from pair to pair.
pub fn clip_flows(
    cfg: &SequenceConfig,
    source: FlowSource,
    predictor: Option<&Predictor>,
    point: OperatingPoint,
    video: VideoOptions,
) -> Result<(ClipData, Option<f64>)> {
    let scene = &cfg.scene;
    let truth = Truth::of(scene)?;
    match (source, predictor) {
        (FlowSource::Truth, _) => {
            let flows = (0..scene.frames - 1)
                .into_par_iter()
                .map(|n| scene.flow(n))
                .collect::<Result<Vec<_>>>()?;
            Ok((
                ClipData {
                    truth,
                    flows,
                    frames: None,
                },
                None,
            ))
        }
        (FlowSource::Mms, Some(p)) => {
            let frames = camera_frames(cfg)?;
            let pairs = pair_flows_scaled(p, frames.as_slice(), point.iters, point.scale, video)?
                .collect::<Result<Vec<_>>>()?;
            let ms = pairs.iter().map(|f| f.ms).sum::<f64>() / pairs.len() as f64;
            let flows = pairs.into_iter().map(|f| f.flow).collect();
            Ok((estimated(truth, flows, &frames), Some(ms)))
        }
        (FlowSource::Dis, _) => {
            let frames = camera_frames(cfg)?;
            let (flows, ms) = crate::flow::dis::sequence_flows(DIS_PYTHON, &frames, "medium")?;
            Ok((estimated(truth, flows, &frames), Some(ms)))
        }
        (FlowSource::Mms, None) => Err(Error::invalid("flow", "MMS flow needs weights")),
    }
}

/// The Python that runs DIS for `"flow": "dis"` (it must import OpenCV and numpy).
pub const DIS_PYTHON: &str = "python3";

/// A clip's frames through its camera, each with its own noise.
pub fn camera_frames(cfg: &SequenceConfig) -> Result<Vec<crate::types::Image>> {
    let scene = &cfg.scene;
    let camera = cfg.camera()?;
    (0..scene.frames)
        .into_par_iter()
        .map(|n| {
            let seed = rng::derive(scene.seed, &[rng::purpose::NOISE_FRAME1, n as u64]);
            camera.apply(&scene.frame(n)?, seed)
        })
        .collect()
}

/// An estimated flow's clip data: the flows with the frames they came from.
fn estimated(truth: Truth, flows: Vec<Flow>, frames: &[crate::types::Image]) -> ClipData {
    ClipData {
        truth,
        flows,
        frames: Some(frames.iter().map(GreyFrame::new).collect()),
    }
}

/// Tracks one clip's flows with one predictor (the background-flow metric included).
pub fn track_clip(data: &ClipData, opts: &TrackOptions) -> Result<Tracks> {
    Ok(track_sequence(
        data.flows.iter().enumerate().map(|(n, f)| {
            Ok(FlowStep {
                name: format!("frame {n}"),
                flow: f.clone(),
                frames: data
                    .frames
                    .as_ref()
                    .and_then(|g| GreyPair::of(g.get(n)?, g.get(n + 1)?)),
            })
        }),
        opts,
        Some(&data.truth),
    )?
    .tracks)
}

/// Runs the experiment; `on_tracks` sees every (clip, predictor, tracks, truth) for plots.
pub fn run(
    cfg: &ExperimentConfig,
    mut on_tracks: impl FnMut(&str, &str, &Tracks, &Truth) -> Result<()>,
) -> Result<ExperimentReport> {
    cfg.validate()?;
    let predictor = match cfg.flow {
        FlowSource::Mms => Some(cfg.track.flow.predictor(burn::prelude::Device::flex())?),
        FlowSource::Truth | FlowSource::Dis => None,
    };
    // Iterations count for MMS only.
    let weights_iters = predictor.as_ref().map_or(0, |p| p.config.iters);
    let video = predictor
        .as_ref()
        .map_or_else(VideoOptions::default, |p| cfg.track.flow.iters_for(p).1);
    let options = (0..cfg.predictors.len())
        .map(|i| cfg.options(i))
        .collect::<Result<Vec<_>>>()?;
    let mut rows = Vec::new();
    let mut switches = Vec::new();
    let mut spurious = Vec::new();
    let mut second = Vec::new();
    let mut missed = Vec::new();
    let mut coverage = Vec::new();
    let mut background = Vec::new();
    let mut flow_ms = Vec::new();
    let mut points = Vec::new();
    let several = cfg.points(weights_iters, 0).len() > 1;
    for clip in &cfg.clips {
        for point in cfg.points(weights_iters, clip.loaded.scene.width) {
            let (data, ms) = clip_flows(&clip.loaded, cfg.flow, predictor.as_ref(), point, video)?;
            flow_ms.extend(ms);
            let mms_point = (cfg.flow == FlowSource::Mms).then_some(point);
            for (p, opts) in cfg.predictors.iter().zip(&options) {
                // With several operating points each (predictor, point) is its own case.
                let name = if several {
                    format!("{} @ {}", p.name, point.label())
                } else {
                    p.name.clone()
                };
                let tracks = track_clip(&data, opts)?;
                if let Some(b) = &tracks.background_flow {
                    let key = if several {
                        format!("{} @ {}", clip.name, point.label())
                    } else {
                        clip.name.clone()
                    };
                    if !background.iter().any(|(c, _)| c == &key) {
                        background.push((key, b.clone()));
                    }
                }
                on_tracks(&clip.name, &name, &tracks, &data.truth)?;
                let report = evaluate(&tracks, &data.truth)?;
                let track_ms = tracks.ms_per_frame.unwrap_or(f64::NAN);
                for o in report.objects.iter().filter(|o| o.truth_index.is_some()) {
                    for e in &o.horizons {
                        rows.push(Row {
                            clip: clip.name.clone(),
                            predictor: name.clone(),
                            object: o.truth_index,
                            track_id: Some(o.id),
                            error: e.clone(),
                            ms_per_frame: track_ms,
                            point: mms_point,
                        });
                    }
                }
                for e in &report.overall {
                    rows.push(Row {
                        clip: clip.name.clone(),
                        predictor: name.clone(),
                        object: None,
                        track_id: None,
                        error: e.clone(),
                        ms_per_frame: track_ms,
                        point: mms_point,
                    });
                }
                let lost = report.false_tracks();
                if let (Some(point), Some(ms)) = (mms_point, ms) {
                    points.push(PointRow {
                        clip: clip.name.clone(),
                        predictor: p.name.clone(),
                        point,
                        flow_ms_per_frame: ms,
                        track_ms_per_frame: track_ms,
                        // Every horizon, NaN (null) where no track reached it.
                        rmse_2d: cfg
                            .horizons
                            .iter()
                            .map(|&h| {
                                let e = report.overall.iter().find(|e| e.horizon == h);
                                (h, e.map_or(f64::NAN, |e| e.rmse_2d))
                            })
                            .collect(),
                        tracks: tracks.objects.len(),
                        id_switches: report.id_switches,
                        spurious: lost,
                        missed: report.missed.len(),
                        background_flow: tracks.background_flow.clone(),
                    });
                }
                switches.push((clip.name.clone(), name.clone(), report.id_switches));
                spurious.push((clip.name.clone(), name.clone(), lost));
                second.push((clip.name.clone(), name.clone(), report.second_tracks()));
                missed.push((clip.name.clone(), name.clone(), report.missed.clone()));
                if let Some(c) = report.coverage {
                    coverage.push((clip.name.clone(), name, c));
                }
            }
        }
    }
    Ok(ExperimentReport {
        flow: cfg.flow,
        flow_ms_per_frame: (!flow_ms.is_empty())
            .then(|| flow_ms.iter().sum::<f64>() / flow_ms.len() as f64),
        rows,
        id_switches: switches,
        spurious,
        second,
        missed,
        coverage,
        background_flow: background,
        points,
    })
}

mod report;
pub use report::{ExperimentReport, Row, table};

#[cfg(test)]
mod tests;
