//! Tracking experiments (Table S5, Note S14): several clips × several predictors, each clip
//! tracked from its exact flow or from MMS flow on its camera frames, every track scored at
//! every horizon, with the run time per frame: one table a reader can compare across.

use std::path::Path;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::coverage::Coverage;
use super::detect::DetectConfig;
use super::eval::{HorizonError, evaluate};
use super::mtp::MtpConfig;
use super::multi::TrackerConfig;
use super::photometric::{GreyFrame, GreyPair};
pub use super::points::{OperatingPoint, PointRow, points_chart, points_table};
use super::run::{FlowStep, TrackOptions, Tracks, track_sequence};
use super::static_flow::BackgroundFlow;
use crate::dataset::sequence::SequenceConfig;
use crate::error::{Error, Result};
use crate::flow::infer::Predictor;
use crate::flow::sequence::pair_flows_scaled;
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
    fn expand(self, base: &Path) -> Result<Vec<ClipSpec>> {
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

/// One named predictor setting.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PredictorSpec {
    pub name: String,
    #[serde(default)]
    pub mtp: MtpConfig,
}

/// An experiment file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExperimentConfig {
    pub clips: Vec<ClipSpec>,
    pub predictors: Vec<PredictorSpec>,
    pub horizons: Vec<usize>,
    #[serde(default = "default_source")]
    pub flow: FlowSource,
    /// MMS weights for `"flow": "mms"` (a file, or built-in: `mms-small`, the default here, `mms-small-real`, `default`) and iterations.
    #[serde(default = "default_weights")]
    pub weights: String,
    #[serde(default = "default_iters")]
    pub iters: usize,
    /// The multiple of the frame size MMS runs at, in (0, 4] (see `flow::scale`).
    #[serde(default = "default_scale")]
    pub scale: f64,
    /// What follows MMS: `"none"` (the default for tracking), `"variational"` or a settings file.
    #[serde(default = "default_refine")]
    pub refine: String,
    /// Where MMS starts: `"zero"` (the default for tracking) or `"coarse"` (from its own flow
    /// at half resolution).
    #[serde(default = "default_start")]
    pub start: String,
    /// Detection: flow magnitude threshold (px/frame) and smallest region (px).
    #[serde(default = "default_threshold")]
    pub threshold: f64,
    #[serde(default = "default_min_area")]
    pub min_area: usize,
    /// Robust noise floor of the threshold, in standard deviations (see `TrackOptions`).
    #[serde(default = "default_noise_k")]
    pub noise_k: f64,
    /// The background model and the photometric test (which runs on MMS clips, whose camera
    /// frames are at hand).
    #[serde(default)]
    pub detect: DetectConfig,
    /// Confirmation window and motion consistency (see `TrackerConfig`); the defaults when absent.
    #[serde(default)]
    pub confirm: Option<usize>,
    /// How far the matching gate widens while a track coasts (`TrackerConfig::max_gate_factor`);
    /// the default when absent.
    #[serde(default)]
    pub max_gate_factor: Option<f64>,
    /// The matching cascade (`TrackerConfig::match_cascade`); off when absent.
    #[serde(default)]
    pub match_cascade: bool,
    /// MMS flow only: the points of the whole system's error-against-run-time curve (flow
    /// resolution and iterations). Empty: one point, full resolution at `iters`.
    #[serde(default)]
    pub operating_points: Vec<OperatingPoint>,
}

fn default_source() -> FlowSource {
    FlowSource::Truth
}
fn default_weights() -> String {
    crate::flow::infer::TRACK_WEIGHTS.into()
}
fn default_iters() -> usize {
    12
}
fn default_scale() -> f64 {
    1.0
}
fn default_refine() -> String {
    "none".into()
}
fn default_start() -> String {
    "zero".into()
}
fn default_threshold() -> f64 {
    0.5
}
fn default_min_area() -> usize {
    20
}
fn default_noise_k() -> f64 {
    3.0
}

impl ExperimentConfig {
    /// The operating points to run: the configured ones, or full resolution at `iters`.
    pub fn points(&self) -> Vec<OperatingPoint> {
        if self.operating_points.is_empty() {
            vec![OperatingPoint {
                scale: self.scale,
                iters: self.iters,
            }]
        } else {
            self.operating_points.clone()
        }
    }

    pub fn from_file(path: &Path) -> Result<Self> {
        let mut cfg: Self = crate::io::read_json(path)?;
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
        crate::flow::infer::parse_start(&self.start).map_err(|_| {
            Error::invalid(
                "start",
                format!("expected \"zero\" or \"coarse\", got {:?}", self.start),
            )
        })?;
        crate::flow::refine::Refine::parse(&self.refine).map_err(|_| {
            Error::invalid(
                "refine",
                format!(
                    "expected \"none\" or \"variational\", got {:?}",
                    self.refine
                ),
            )
        })?;
        if self.horizons.is_empty() || self.horizons.iter().any(|&h| h == 0 || h > 10_000) {
            return Err(Error::invalid("horizons", "need horizons in 1..=10000"));
        }
        if !(self.threshold.is_finite() && self.threshold >= 0.0) {
            return Err(Error::invalid("threshold", "must be finite and >= 0"));
        }
        if !(self.noise_k.is_finite() && self.noise_k >= 0.0) {
            return Err(Error::invalid("noise_k", "must be finite and >= 0"));
        }
        crate::flow::scale::check_scale(self.scale)?;
        if self.scale != 1.0 && self.flow != FlowSource::Mms {
            return Err(Error::invalid(
                "scale",
                "only MMS flow runs at a scale (set \"flow\": \"mms\")",
            ));
        }
        self.detect.validate()?;
        if self.confirm == Some(0) {
            return Err(Error::invalid("confirm", "must be >= 1"));
        }
        if let Some(f) = self.max_gate_factor
            && !(f >= 1.0 && f.is_finite())
        {
            return Err(Error::invalid(
                "max_gate_factor",
                format!("must be finite and >= 1, got {f}"),
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
        for p in &self.predictors {
            p.mtp.validate()?;
        }
        Ok(())
    }
}

/// One row of the result: a clip, a predictor, one tracked object (or `all`), one horizon.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Row {
    pub clip: String,
    pub predictor: String,
    /// The true object index, or null for the pooled row.
    pub object: Option<usize>,
    pub track_id: Option<usize>,
    #[serde(flatten)]
    pub error: HorizonError,
    pub ms_per_frame: f64,
    /// The operating point (MMS flow; absent for exact flow).
    #[serde(default)]
    pub point: Option<OperatingPoint>,
}

/// The whole result.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ExperimentReport {
    pub flow: FlowSource,
    /// Flow estimation time per frame (estimated flow only).
    pub flow_ms_per_frame: Option<f64>,
    pub rows: Vec<Row>,
    /// (clip, predictor) → ID switches.
    pub id_switches: Vec<(String, String, usize)>,
    /// (clip, predictor) → tracks that follow no object.
    #[serde(default)]
    pub spurious: Vec<(String, String, usize)>,
    /// (clip, predictor) → second tracks: on an object another track follows (picked up
    /// again under a new ID).
    #[serde(default)]
    pub second: Vec<(String, String, usize)>,
    /// (clip, predictor) → true objects followed by no track.
    #[serde(default)]
    pub missed: Vec<(String, String, Vec<usize>)>,
    /// (clip, predictor) → how much of the objects the tracks cover and IDF1.
    #[serde(default)]
    pub coverage: Vec<(String, String, Coverage)>,
    /// Clip → background-flow magnitude of its flows.
    #[serde(default)]
    pub background_flow: Vec<(String, BackgroundFlow)>,
    /// MMS flow: one row per clip, operating point and predictor.
    #[serde(default)]
    pub points: Vec<PointRow>,
}

/// A clip's flows and truth, computed once and shared by every predictor.
pub struct ClipData {
    pub truth: Truth,
    pub flows: Vec<Flow>,
    /// The camera frames (MMS clips), for the photometric test.
    pub frames: Option<Vec<GreyFrame>>,
}

/// The flows of a clip: exact, or MMS on its camera frames (`predictor` must then be given).
pub fn clip_flows(
    cfg: &SequenceConfig,
    source: FlowSource,
    predictor: Option<&Predictor>,
    point: OperatingPoint,
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
            let pairs = pair_flows_scaled(p, frames.as_slice(), point.iters, point.scale)
                .collect::<Result<Vec<_>>>()?;
            let ms = pairs.iter().map(|f| f.ms).sum::<f64>() / pairs.len() as f64;
            let flows = pairs.into_iter().map(|f| f.flow).collect();
            Ok((estimated(truth, flows, &frames), Some(ms)))
        }
        (FlowSource::Dis, _) => {
            let frames = camera_frames(cfg)?;
            let (flows, ms) = crate::flow::dis::sequence_flows(DIS_PYTHON, &frames)?;
            Ok((estimated(truth, flows, &frames), Some(ms)))
        }
        (FlowSource::Mms, None) => Err(Error::invalid("flow", "MMS flow needs weights")),
    }
}

/// The Python that runs DIS for `"flow": "dis"` (it must import OpenCV and numpy).
pub const DIS_PYTHON: &str = "python3";

/// A clip's frames through its camera, each with its own noise.
fn camera_frames(cfg: &SequenceConfig) -> Result<Vec<crate::types::Image>> {
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
        FlowSource::Mms => Some(
            Predictor::load(&cfg.weights)?
                .with_refine(&crate::flow::refine::Refine::parse(&cfg.refine)?)
                .with_coarse_start(crate::flow::infer::parse_start(&cfg.start)?),
        ),
        FlowSource::Truth | FlowSource::Dis => None,
    };
    let mut rows = Vec::new();
    let mut switches = Vec::new();
    let mut spurious = Vec::new();
    let mut second = Vec::new();
    let mut missed = Vec::new();
    let mut coverage = Vec::new();
    let mut background = Vec::new();
    let mut flow_ms = Vec::new();
    let mut points = Vec::new();
    let several = cfg.points().len() > 1;
    for clip in &cfg.clips {
        for point in cfg.points() {
            let (data, ms) = clip_flows(&clip.loaded, cfg.flow, predictor.as_ref(), point)?;
            flow_ms.extend(ms);
            let mms_point = (cfg.flow == FlowSource::Mms).then_some(point);
            let estimated_flow = cfg.flow != FlowSource::Truth;
            for p in &cfg.predictors {
                // With several operating points each (predictor, point) is its own case.
                let name = if several {
                    format!("{} @ {}", p.name, point.label())
                } else {
                    p.name.clone()
                };
                let opts = TrackOptions {
                    tracker: TrackerConfig {
                        mtp: p.mtp.clone(),
                        confirm: cfg.confirm.unwrap_or(TrackerConfig::default().confirm),
                        max_gate_factor: cfg
                            .max_gate_factor
                            .unwrap_or(TrackerConfig::default().max_gate_factor),
                        match_cascade: cfg.match_cascade,
                        ..TrackerConfig::default()
                    },
                    horizons: cfg.horizons.clone(),
                    threshold: cfg.threshold,
                    noise_k: cfg.noise_k,
                    min_area: cfg.min_area,
                    detect: cfg.detect.resolved(estimated_flow),
                    debug: false,
                };
                let tracks = track_clip(&data, &opts)?;
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

/// The report as a text table.
pub fn table(r: &ExperimentReport) -> String {
    let mut s = format!(
        "{:<12} {:<22} {:>6} {:>7} {:>6} {:>9} {:>9} {:>9} {:>8}\n",
        "clip",
        "predictor",
        "object",
        "horizon",
        "count",
        "RMSE_X",
        "RMSE_Y",
        "RMSE_2D",
        "ms/frame"
    );
    for row in &r.rows {
        let obj = row.object.map_or("all".to_string(), |o| o.to_string());
        s += &format!(
            "{:<12} {:<22} {:>6} {:>7} {:>6} {:>9.2} {:>9.2} {:>9.2} {:>8.3}\n",
            row.clip,
            row.predictor,
            obj,
            row.error.horizon,
            row.error.count,
            row.error.rmse_x,
            row.error.rmse_y,
            row.error.rmse_2d,
            row.ms_per_frame
        );
    }
    for (c, p, n) in &r.id_switches {
        if *n > 0 {
            s += &format!("{c} / {p}: {n} ID switches\n");
        }
    }
    for (c, p, n) in &r.spurious {
        if *n > 0 {
            s += &format!("{c} / {p}: {n} tracks follow no object\n");
        }
    }
    for (c, p, n) in &r.second {
        if *n > 0 {
            s += &format!("{c} / {p}: {n} second tracks on an object another track follows\n");
        }
    }
    for (c, p, m) in &r.missed {
        if !m.is_empty() {
            s += &format!("{c} / {p}: missed objects {m:?}\n");
        }
    }
    for (c, p, v) in &r.coverage {
        s += &format!(
            "{c} / {p}: coverage {:.1} % (mostly tracked {}, partially {}, mostly lost {}), IDF1 {:.3}\n",
            100.0 * v.recall,
            v.mostly_tracked,
            v.partially_tracked,
            v.mostly_lost,
            v.idf1
        );
    }
    for (c, b) in &r.background_flow {
        s += &format!(
            "{c}: background flow mean {:.3} px, p99 {:.3} px\n",
            b.mean, b.p99
        );
    }
    if let Some(ms) = r.flow_ms_per_frame {
        let name = if r.flow == FlowSource::Dis {
            "DIS"
        } else {
            "MMS"
        };
        s += &format!("{name} flow: {ms:.0} ms per frame\n");
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    const SCENE: &str = r#"{"scene": {"width": 64, "height": 48, "frames": 4, "seed": 7,
        "objects": [{"path": "sinusoid", "radius": 6}]}}"#;

    fn load(dir: &Path, clips: &str) -> Result<ExperimentConfig> {
        std::fs::write(dir.join("clip.json"), SCENE).unwrap();
        let path = dir.join("experiment.json");
        std::fs::write(
            &path,
            format!(r#"{{"clips": {clips}, "predictors": [{{"name": "poly"}}], "horizons": [1]}}"#),
        )
        .unwrap();
        ExperimentConfig::from_file(&path)
    }

    #[test]
    fn clips_come_from_files_or_inline_once_per_seed() {
        let dir = tempfile::tempdir().unwrap();
        let cfg = load(
            dir.path(),
            &format!(
                r#"[{{"name": "file", "config": "clip.json"}},
                    {{"name": "seeded", "config": "clip.json", "seeds": [3, 4]}},
                    {{"name": "inline", "clip": {SCENE}, "seeds": [9]}}]"#
            ),
        )
        .unwrap();
        let runs: Vec<(&str, u64)> = cfg
            .clips
            .iter()
            .map(|c| (c.name.as_str(), c.loaded.scene.seed))
            .collect();
        assert_eq!(
            runs,
            [
                ("file", 7),
                ("seeded_seed3", 3),
                ("seeded_seed4", 4),
                ("inline_seed9", 9)
            ]
        );
        // Apart from the seed, a seeded run is the clip itself.
        let mut c = cfg.clips[1].loaded.clone();
        c.scene.seed = 7;
        assert_eq!(c, cfg.clips[0].loaded);
    }

    #[test]
    fn clip_specs_that_say_too_little_or_repeat_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let err = |clips: &str| load(dir.path(), clips).unwrap_err().to_string();
        assert!(err(r#"[{"name": "a"}]"#).contains("needs either"));
        let both = format!(r#"[{{"name": "a", "config": "clip.json", "clip": {SCENE}}}]"#);
        assert!(err(&both).contains("needs either"));
        assert!(
            err(r#"[{"name": "a", "config": "clip.json", "seeds": [1, 1]}]"#).contains("seed 1")
        );
        let twice =
            r#"[{"name": "a", "config": "clip.json"}, {"name": "a", "config": "clip.json"}]"#;
        assert!(err(twice).contains("two clips are named"));
        let missing = err(r#"[{"name": "a", "config": "nowhere.json"}]"#);
        assert!(missing.contains("nowhere.json"), "{missing}");
    }
}
