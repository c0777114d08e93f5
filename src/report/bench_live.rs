//! The live system's error against run time (Notes S1, S13–S15 at the camera's rate): for each
//! operating point (flow resolution, iterations, reuse, warm start, refinement) and for DIS's
//! presets, on rendered clips with exact flow and object truth,
//!
//! - the flow's EPE (all pixels and moving pixels) against its ms per pair, every camera frame;
//! - the rate it sustains on a stream at the clip's frame rate: a pipeline that needs `ms` per
//!   pair keeps one frame in `k = ⌈ms · fps / 1000⌉` (the others arrive while it works), so it
//!   runs on frames 0, k, 2k, …;
//! - the tracker's error one processed frame ahead at that rate (flow between the kept frames,
//!   the truth at them), beside the same error had it kept every frame.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::flow::dis;
use crate::flow::iters::Iters;
use crate::flow::metrics::FlowErrorSums;
use crate::flow::sequence::pair_flows_scaled;
use crate::scene::truth::Truth;
use crate::track::config::{Profile, TrackConfig};
use crate::track::detect::photometric::GreyFrame;
use crate::track::eval::rmse::evaluate;
use crate::track::experiment::{ClipData, ClipSpec, camera_frames, track_clip};
use crate::types::{Flow, Image};

/// Flow magnitude (px) from which a truth pixel counts as moving.
const MOVING_PX: f32 = 0.5;

/// One operating point: `track.flow` with these keys replaced.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LivePoint {
    pub name: String,
    #[serde(default)]
    pub iters: Option<Iters>,
    #[serde(default)]
    pub scale: Option<f64>,
    #[serde(default)]
    pub reuse: Option<bool>,
    #[serde(default)]
    pub warm_start: Option<bool>,
    #[serde(default)]
    pub refine: Option<String>,
    #[serde(default)]
    pub start: Option<String>,
}

/// `pins bench-live`'s config.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LiveBenchConfig {
    pub clips: Vec<ClipSpec>,
    /// The tracking settings (the estimated profile unless it names another); `track.flow` is
    /// the base of every point.
    #[serde(default)]
    pub track: TrackConfig,
    pub points: Vec<LivePoint>,
    /// DIS presets run on the same frames (`medium`, `fast`, `ultrafast`).
    #[serde(default)]
    pub dis: Vec<String>,
}

impl LiveBenchConfig {
    /// Reads a config; clip files are relative to it.
    pub fn from_file(path: &Path) -> Result<Self> {
        let mut cfg: Self = crate::io::read_json(path)?;
        let base = path.parent().unwrap_or(Path::new(""));
        let clips = std::mem::take(&mut cfg.clips);
        for c in clips {
            cfg.clips.extend(c.expand(base)?);
        }
        cfg.validate().map_err(|e| crate::io::in_config(path, e))?;
        Ok(cfg)
    }

    pub fn validate(&self) -> Result<()> {
        if self.clips.is_empty() || self.points.is_empty() && self.dis.is_empty() {
            return Err(Error::invalid(
                "bench-live",
                "needs clips and at least one point or DIS preset",
            ));
        }
        for p in &self.points {
            self.flow_of(p)?;
        }
        for d in &self.dis {
            if !dis::PRESETS.contains(&d.as_str()) {
                return Err(Error::invalid(
                    "dis",
                    format!("expected presets among {:?}, got {d:?}", dis::PRESETS),
                ));
            }
        }
        Ok(())
    }

    /// The tracking config of point `p`.
    fn flow_of(&self, p: &LivePoint) -> Result<TrackConfig> {
        let mut c = self.track.clone();
        let f = &mut c.flow;
        if let Some(n) = p.iters {
            f.iters = Some(n);
        }
        if let Some(s) = p.scale {
            f.scale = Some(s);
        }
        if let Some(r) = p.reuse {
            f.reuse = r;
        }
        if let Some(w) = p.warm_start {
            f.warm_start = w;
        }
        if let Some(r) = &p.refine {
            f.refine = r.clone();
        }
        if let Some(s) = &p.start {
            f.start = s.clone();
        }
        f.validate()
            .map_err(|e| Error::invalid(format!("point {:?}", p.name), e.to_string()))?;
        Ok(c)
    }
}

/// One method on one clip.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct LiveRow {
    pub clip: String,
    pub method: String,
    /// Flow time per pair (the network and its refinement, or DIS's own), every frame.
    pub ms_per_pair: f64,
    /// Tracking time per processed frame.
    pub track_ms: f64,
    /// Frames per second it processes on a stream at `stream_fps`, and the stride `k`.
    pub processed_fps: f64,
    pub stride: usize,
    pub stream_fps: f64,
    /// Flow accuracy over every pair: all pixels and moving pixels.
    pub epe: f64,
    pub epe_moving: f64,
    /// Tracking RMSE one frame ahead (px) keeping every frame, and at the processed rate (one
    /// processed frame ahead); NaN where nothing was scored.
    pub rmse1_every_frame: f64,
    pub rmse1_live: f64,
    /// Share of the objects' in-view frames covered by a track, at the processed rate (NaN, and
    /// no ID switches, where fewer than three frames are kept).
    pub recall_live: f64,
    pub id_switches_live: usize,
}

/// Runs every point and preset on every clip, MMS on `device` (DIS always on the CPU); `log`
/// sees progress lines.
pub fn run(
    cfg: &LiveBenchConfig,
    python: &str,
    device: &burn::prelude::Device,
    log: &dyn Fn(&str),
) -> Result<Vec<LiveRow>> {
    cfg.validate()?;
    let mut rows = Vec::new();
    for clip in &cfg.clips {
        let scene = &clip.loaded.scene;
        let frames = camera_frames(&clip.loaded)?;
        let truth_flows = (0..frames.len() - 1)
            .map(|n| scene.flow(n))
            .collect::<Result<Vec<_>>>()?;
        let truth = Truth::of(scene)?;
        let base = Base {
            frames: &frames,
            truth_flows: &truth_flows,
            truth: &truth,
            fps: scene.fps,
        };
        for p in &cfg.points {
            let tc = cfg.flow_of(p)?;
            let predictor = tc.flow.predictor(device.clone())?;
            let (iters, video) = tc.flow.iters_for(&predictor);
            let estimate = |f: &[Image]| -> Result<(Vec<Flow>, f64)> {
                let width = f.first().map_or(0, |i| i.width());
                let pairs =
                    pair_flows_scaled(&predictor, f, iters, tc.flow.scale_for(width), video)?
                        .collect::<Result<Vec<_>>>()?;
                let ms = pairs.iter().map(|p| p.ms).sum::<f64>() / pairs.len().max(1) as f64;
                Ok((pairs.into_iter().map(|p| p.flow).collect(), ms))
            };
            let row = base.row(&clip.name, &p.name, &tc, &estimate)?;
            log(&row_line(&row));
            rows.push(row);
        }
        for preset in &cfg.dis {
            let estimate = |f: &[Image]| dis::sequence_flows(python, f, preset);
            let row = base.row(&clip.name, &format!("DIS {preset}"), &cfg.track, &estimate)?;
            log(&row_line(&row));
            rows.push(row);
        }
    }
    Ok(rows)
}

/// A method's flows for a sequence of frames, with its ms per pair.
type Estimate<'a> = dyn Fn(&[Image]) -> Result<(Vec<Flow>, f64)> + 'a;

/// One clip's frames and truth.
struct Base<'a> {
    frames: &'a [Image],
    truth_flows: &'a [Flow],
    truth: &'a Truth,
    fps: f64,
}

impl Base<'_> {
    /// Scores one method: its flow on every pair, then tracking every frame and at its rate.
    fn row(
        &self,
        clip: &str,
        method: &str,
        tc: &TrackConfig,
        estimate: &Estimate,
    ) -> Result<LiveRow> {
        let mut opts = tc.options(Profile::Estimated, false)?;
        opts.horizons = vec![1];
        let (flows, ms) = estimate(self.frames)?;
        let (mut all, mut moving) = (FlowErrorSums::default(), FlowErrorSums::default());
        for (f, t) in flows.iter().zip(self.truth_flows) {
            all.add(f, t, None)?;
            let mask: Vec<bool> = (0..t.height() * t.width())
                .map(|i| {
                    let (u, v) = t.get(i / t.width(), i % t.width());
                    u.hypot(v) >= MOVING_PX
                })
                .collect();
            moving.add(f, t, Some(&mask))?;
        }
        let every = ClipData {
            truth: self.truth.clone(),
            flows,
            frames: Some(self.frames.iter().map(GreyFrame::new).collect()),
        };
        let tracks = track_clip(&every, &opts)?;
        let track_ms = tracks.ms_per_frame.unwrap_or(0.0);
        let rmse1_every_frame = one_ahead(&evaluate(&tracks, self.truth)?);
        // The frames a pipeline that needs ms + track_ms per frame keeps from the stream.
        let stride = ((ms + track_ms) * self.fps / 1e3).ceil().max(1.0) as usize;
        let kept: Vec<Image> = self.frames.iter().step_by(stride).cloned().collect();
        let truth = self.truth.every(stride);
        // Fewer than three kept frames give no track to score: the live columns stay empty.
        let report = if stride == 1 {
            Some(evaluate(&tracks, self.truth)?)
        } else if kept.len() < 3 {
            None
        } else {
            let (flows, _) = estimate(&kept)?;
            let live = ClipData {
                truth: truth.clone(),
                flows,
                frames: Some(kept.iter().map(GreyFrame::new).collect()),
            };
            Some(evaluate(&track_clip(&live, &opts)?, &truth)?)
        };
        Ok(LiveRow {
            clip: clip.to_string(),
            method: method.to_string(),
            ms_per_pair: ms,
            track_ms,
            processed_fps: self.fps / stride as f64,
            stride,
            stream_fps: self.fps,
            epe: all.scores().epe,
            epe_moving: moving.scores().epe,
            rmse1_every_frame,
            rmse1_live: report.as_ref().map_or(f64::NAN, one_ahead),
            recall_live: report
                .as_ref()
                .and_then(|r| r.coverage.as_ref())
                .map_or(f64::NAN, |c| c.recall),
            id_switches_live: report.as_ref().map_or(0, |r| r.id_switches),
        })
    }
}

/// The pooled RMSE one frame ahead (NaN where nothing was scored).
fn one_ahead(r: &crate::track::eval::rmse::TrackReport) -> f64 {
    r.overall
        .iter()
        .find(|h| h.horizon == 1)
        .map_or(f64::NAN, |h| h.rmse_2d)
}

fn row_line(r: &LiveRow) -> String {
    format!(
        "{} / {}: {:.0} ms per pair, {:.1} of {:.0} fps (1 in {}), EPE {:.3} (moving {:.3}), \
         RMSE@1 {:.2} every frame, {:.2} live, recall {:.2}",
        r.clip,
        r.method,
        r.ms_per_pair,
        r.processed_fps,
        r.stream_fps,
        r.stride,
        r.epe,
        r.epe_moving,
        r.rmse1_every_frame,
        r.rmse1_live,
        r.recall_live
    )
}

/// The rows as a markdown table, one per clip and method.
pub fn markdown(rows: &[LiveRow]) -> String {
    let mut s = String::from(
        "| clip | method | ms per pair | processed fps (stream) | EPE | EPE moving | RMSE@1 every frame | RMSE@1 live | recall live | ID switches live |\n|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        s += &format!(
            "| {} | {} | {:.0} (+{:.0} tracking) | {:.1} ({:.0}, 1 in {}) | {:.3} | {:.3} | {} | {} | {} | {} |\n",
            r.clip,
            r.method,
            r.ms_per_pair,
            r.track_ms,
            r.processed_fps,
            r.stream_fps,
            r.stride,
            r.epe,
            r.epe_moving,
            num(r.rmse1_every_frame),
            num(r.rmse1_live),
            num(r.recall_live),
            r.id_switches_live
        );
    }
    s
}

fn num(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.2}")
    } else {
        "–".into()
    }
}

/// Two charts per clip: flow EPE against ms per pair, and tracking error one frame ahead against
/// processed fps; one labelled marker per method.
pub fn charts(rows: &[LiveRow]) -> Vec<(String, crate::io::chart::Chart)> {
    use crate::io::chart::{Chart, Series};
    let mut clips: Vec<&str> = rows.iter().map(|r| r.clip.as_str()).collect();
    clips.dedup();
    let mut out = Vec::new();
    for clip in clips {
        let of = |x: fn(&LiveRow) -> f64, y: fn(&LiveRow) -> f64| {
            rows.iter()
                .filter(|r| r.clip == clip && y(r).is_finite())
                .map(|r| Series {
                    name: r.method.clone(),
                    points: vec![(x(r), y(r))],
                    markers: true,
                })
                .collect::<Vec<_>>()
        };
        let (epe, track) = (
            of(|r| r.ms_per_pair, |r| r.epe),
            of(|r| r.processed_fps, |r| r.rmse1_live),
        );
        // A chart with nothing to plot (no method tracked at its rate) is left out.
        if !epe.is_empty() {
            out.push((
                format!("epe_vs_ms_{clip}.png"),
                Chart {
                    title: format!("{clip}: flow error against time"),
                    x_label: "ms per pair".into(),
                    y_label: "EPE (px)".into(),
                    series: epe,
                    log_y: false,
                },
            ));
        }
        if !track.is_empty() {
            out.push((
                format!("track_vs_fps_{clip}.png"),
                Chart {
                    title: format!("{clip}: tracking one frame ahead against processed fps"),
                    x_label: "processed fps".into(),
                    y_label: "RMSE one processed frame ahead (px)".into(),
                    series: track,
                    log_y: false,
                },
            ));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config(points: &str, dis: &str) -> Result<LiveBenchConfig> {
        let text = format!(
            r#"{{"clips": [{{"name": "c", "clip": {{"scene": {{"width": 64, "height": 48,
                "fps": 15, "frames": 6, "seed": 1, "objects": [{{"path": "sinusoid", "radius": 4}}]}}}}}}],
              "points": {points}, "dis": {dis}}}"#
        );
        let dir = tempfile::tempdir().map_err(|e| Error::io(Path::new("tmp"), e))?;
        let path = dir.path().join("bench_live.json");
        std::fs::write(&path, text).map_err(|e| Error::io(&path, e))?;
        LiveBenchConfig::from_file(&path)
    }

    #[test]
    fn points_lay_their_keys_over_the_tracking_flow() {
        let cfg = config(
            r#"[{"name": "a", "iters": "auto", "warm_start": true, "scale": 0.5}]"#,
            r#"["fast"]"#,
        )
        .expect("a good config");
        let tc = cfg.flow_of(&cfg.points[0]).expect("point");
        assert_eq!(tc.flow.iters, Some(Iters::Auto));
        assert!(tc.flow.warm_start && tc.flow.reuse);
        assert_eq!(tc.flow.scale, Some(0.5));
        assert_eq!(cfg.clips[0].loaded.scene.frames, 6);
    }

    #[test]
    fn bad_points_and_presets_are_named() {
        let err = |points: &str, dis: &str| {
            config(points, dis)
                .err()
                .map(|e| e.to_string())
                .unwrap_or_default()
        };
        assert!(err(r#"[{"name": "x", "scale": 9}]"#, "[]").contains("\"x\""));
        assert!(err(r#"[{"name": "x", "iters": 0}]"#, "[]").contains("iters"));
        assert!(err("[]", r#"["slow"]"#).contains("slow"));
        assert!(err("[]", "[]").contains("at least one point"));
        assert!(err(r#"[{"name": "x", "speed": 1}]"#, "[]").contains("speed"));
    }

    #[test]
    fn the_table_and_charts_have_one_entry_per_method() {
        let row = |method: &str, ms: f64| LiveRow {
            clip: "c".into(),
            method: method.into(),
            ms_per_pair: ms,
            track_ms: 1.0,
            processed_fps: 7.5,
            stride: 2,
            stream_fps: 15.0,
            epe: 0.5,
            epe_moving: 2.0,
            rmse1_every_frame: 1.5,
            rmse1_live: f64::NAN,
            recall_live: 0.5,
            id_switches_live: 0,
        };
        let rows = [row("a", 80.0), row("b", 40.0)];
        let md = markdown(&rows);
        assert_eq!(md.lines().count(), 4);
        assert!(
            md.contains("| c | b | 40 (+1 tracking) | 7.5 (15, 1 in 2) |"),
            "{md}"
        );
        let charts = charts(&rows);
        assert_eq!(charts[0].1.series.len(), 2);
        // A NaN error is left off the chart, not drawn, and a chart left empty is not made.
        assert_eq!(charts.len(), 1);
    }
}
