//! Tracking a sequence of flow maps into `tracks.json`: regions per frame, the multi-object
//! tracker, and each object's predictions at the requested horizons.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Serialize;

use super::detect::photometric::GreyPair;
use super::detect::static_flow::{BackgroundFlow, StaticFlow};
use super::detect::{DetectConfig, detect};
use super::tracker::multi::{Assignment, Held, Tracker, TrackerConfig};
use super::tracker::tracks::{FrameRecord, ObjectTrack, Tracks};
use crate::error::{Error, Result};
use crate::io;
use crate::scene::truth::Truth;
use crate::types::Flow;

/// Options of a run: a `TrackConfig` settled by its profile (`TrackConfig::options`).
#[derive(Clone, Debug)]
pub struct TrackOptions {
    pub tracker: TrackerConfig,
    pub horizons: Vec<usize>,
    /// Flow magnitude (px/frame) above which a pixel moves.
    pub threshold: f64,
    /// The threshold also rises to the frame's median magnitude plus this many robust standard
    /// deviations (1.4826 × MAD), so the background jitter of an estimated flow is not motion;
    /// on an exact flow of a still background this changes nothing. 0 turns it off.
    pub noise_k: f64,
    pub min_area: usize,
    /// The background model and the photometric test.
    pub detect: DetectConfig,
    /// Keep every frame's regions and verdicts (`TrackRun::debug`).
    pub debug: bool,
}

impl TrackOptions {
    /// Checks every option, naming the key of the first bad one.
    pub fn validate(&self) -> Result<()> {
        if self.horizons.is_empty() || self.horizons.iter().any(|&h| h == 0 || h > 10_000) {
            return Err(Error::invalid("horizons", "need horizons in 1..=10000"));
        }
        if !(self.threshold.is_finite() && self.threshold >= 0.0) {
            return Err(Error::invalid(
                "threshold",
                format!(
                    "must be a finite number >= 0 (px/frame), got {}",
                    self.threshold
                ),
            ));
        }
        if !(self.noise_k.is_finite() && self.noise_k >= 0.0) {
            return Err(Error::invalid(
                "noise_k",
                format!("must be a finite number >= 0, got {}", self.noise_k),
            ));
        }
        self.detect.validate()?;
        self.tracker.validate()
    }
}

/// One frame's flow (frame n → n + 1), with the two frames when the photometric test is to run.
pub struct FlowStep {
    pub name: String,
    pub flow: Flow,
    pub frames: Option<GreyPair>,
}

/// A run's result: the tracks, and per frame the regions and what became of them (when
/// `TrackOptions::debug` is set).
pub struct TrackRun {
    pub tracks: Tracks,
    pub debug: Vec<DebugFrame>,
}

/// One line of `regions.jsonl`.
#[derive(Clone, Debug, Serialize)]
pub struct DebugFrame {
    pub frame: usize,
    /// The magnitude threshold used (px/frame, relative to the background).
    pub threshold: f64,
    /// The change test's level (grey levels in [0, 1]); null when it did not run.
    pub change_level: Option<f64>,
    /// The background model's flow at the frame centre and its largest magnitude at a corner.
    pub background_centre: [f64; 2],
    pub background_max: f64,
    /// The fitted background motion at the frame centre when the frames did not support it
    /// (it was subtracted from the flow, but the change and photometric tests took the
    /// background as still).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub background_rejected: Option<[f64; 2]>,
    /// False when the frames support the fitted motion no more than its warp's interpolation
    /// of their noise does (`GreyPair::explains`): the placement took the camera as still.
    pub background_explained: bool,
    pub regions: Vec<DebugRegion>,
    /// Tentative tracks with a full but inconsistent confirmation window.
    pub held: Vec<Held>,
}

/// One region in `regions.jsonl`.
#[derive(Clone, Debug, Serialize)]
pub struct DebugRegion {
    /// `[x_min, y_min, x_max, y_max]`.
    pub bbox: [usize; 4],
    pub area: usize,
    /// The flow's centroid (association and confirmation).
    pub centroid: [f64; 2],
    /// The object's centre in the frame, when the still background placed it (the trajectory
    /// filter's measurement).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub placed: Option<[f64; 2]>,
    /// What the still background did with the centroid (accepted regions, when it ran).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub placement: Option<String>,
    /// The mean colour at its centre (R, G, B, 8-bit levels; the tracker's appearance cue).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub colour: Option<[f64; 3]>,
    pub mean_flow: [f64; 2],
    /// The motion the frames confirm (`track::detect::align`), when the alignment ran and beat the
    /// mean flow.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub aligned: Option<[f64; 2]>,
    pub speed: f64,
    /// Mean warp residual with the region's flow and with the background's motion, and their
    /// ratio (null without frames).
    pub residual_flow: Option<f64>,
    pub residual_background: Option<f64>,
    pub residual_ratio: Option<f64>,
    pub accepted: bool,
    pub reason: String,
    /// The track it went to (accepted regions only).
    pub track: Option<Assignment>,
}

/// The `.flo` files of a folder, sorted by name.
pub fn flow_files(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| Error::io(dir, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("flo")))
        .collect();
    v.sort();
    if v.is_empty() {
        return Err(Error::invalid(
            "--flows",
            format!("{} holds no .flo files", dir.display()),
        ));
    }
    Ok(v)
}

/// Tracks a folder of flows (with the frames, `frames.len() == files.len() + 1`, for the
/// photometric test).
pub fn track_flows(
    files: &[PathBuf],
    frames: Option<&[PathBuf]>,
    opts: &TrackOptions,
    truth: Option<&Truth>,
) -> Result<TrackRun> {
    if let Some(fr) = frames
        && fr.len() != files.len() + 1
    {
        return Err(Error::invalid(
            "--frames",
            format!(
                "{} frames for {} flows: need one frame more than flows",
                fr.len(),
                files.len()
            ),
        ));
    }
    let mut prev: Option<super::detect::photometric::GreyFrame> = None;
    let steps = files.iter().enumerate().map(move |(n, f)| {
        let flow = io::read_flow(f)?;
        let pair = match frames {
            Some(fr) => {
                let a = match prev.take() {
                    Some(a) => a,
                    None => super::detect::photometric::GreyFrame::new(&io::read_image(&fr[n])?),
                };
                let b = super::detect::photometric::GreyFrame::new(&io::read_image(&fr[n + 1])?);
                let pair = GreyPair::of(&a, &b).ok_or_else(|| {
                    Error::invalid(
                        format!("frames {} and {}", fr[n].display(), fr[n + 1].display()),
                        "differ in size or are empty",
                    )
                })?;
                prev = Some(b);
                Some(pair)
            }
            None => None,
        };
        Ok(FlowStep {
            name: f.display().to_string(),
            flow,
            frames: pair,
        })
    });
    track_sequence(steps, opts, truth)
}

/// Tracks a sequence of flows (frame n → n + 1, in order). With a truth, the background-flow
/// magnitude of the flows is measured too (`Tracks::background_flow`).
pub fn track_sequence(
    flows: impl Iterator<Item = Result<FlowStep>>,
    opts: &TrackOptions,
    truth: Option<&Truth>,
) -> Result<TrackRun> {
    opts.validate()?;
    let max_h = *opts.horizons.iter().max().unwrap_or(&1);
    let mut tracker = Tracker::new(opts.tracker.clone())?;
    let mut objects: BTreeMap<usize, Vec<FrameRecord>> = BTreeMap::new();
    let mut size: Option<(usize, usize)> = None;
    let mut busy = std::time::Duration::ZERO;
    let mut count = 0usize;
    let mut debug = Vec::new();
    let mut still = truth
        .map(|t| StaticFlow::new(t, STATIC_MARGIN_PX))
        .transpose()?;
    let mut placer = opts.detect.still_background()?;
    for (frame, item) in flows.enumerate() {
        let step = item?;
        let (name, flow) = (&step.name, &step.flow);
        let started = std::time::Instant::now();
        let s = (flow.height(), flow.width());
        if let Some(first) = size
            && first != s
        {
            return Err(Error::shape(
                format!("flow {name}"),
                format!("{}x{} (the first flow)", first.1, first.0),
                format!("{}x{}", s.1, s.0),
            ));
        }
        size = Some(s);
        if let Some(p) = &step.frames
            && (p.width, p.height) != (s.1, s.0)
        {
            return Err(Error::shape(
                format!("frames of flow {name}"),
                format!("{}x{} (the flow)", s.1, s.0),
                format!("{}x{}", p.width, p.height),
            ));
        }
        let mut found = detect(
            flow,
            step.frames.as_ref(),
            opts.threshold,
            opts.noise_k,
            opts.min_area,
            &opts.detect,
        )
        .map_err(|e| Error::invalid(format!("flow {name}"), e.to_string()))?;
        if let (Some(model), Some(pair)) = (placer.as_mut(), step.frames.as_ref()) {
            found.place(model, pair.first_colour(), &tracker.seeds());
        }
        if let Some(pair) = step.frames.as_ref() {
            found.colour(pair.first_colour());
        }
        let dets = found.accepted();
        tracker.set_frame_size(s.1, s.0);
        for t in tracker.step(frame, &dets, max_h)? {
            let e = &t.estimate;
            let predicted = opts
                .horizons
                .iter()
                .map(|&h| (h.to_string(), [e.path[h - 1].0, e.path[h - 1].1]))
                .collect();
            objects.entry(t.id).or_default().push(FrameRecord {
                frame,
                centroid: [e.centroid.0, e.centroid.1],
                speed: e.speed,
                direction: e.direction,
                observed: t.observed,
                predicted,
                path: e.path.iter().map(|p| [p.0, p.1]).collect(),
            });
        }
        busy += started.elapsed();
        count += 1;
        if let Some(st) = still.as_mut() {
            st.add(frame, flow)?;
        }
        if opts.debug {
            let mut assigned = tracker.assignments.iter();
            let (cx, cy) = ((s.1 as f64 - 1.0) / 2.0, (s.0 as f64 - 1.0) / 2.0);
            let bc = found.background.at(cx, cy);
            debug.push(DebugFrame {
                frame,
                threshold: found.threshold,
                change_level: found.change_level,
                background_centre: [bc.0, bc.1],
                background_max: found.background.max_magnitude(s.1, s.0),
                background_rejected: found.rejected_background.map(|g| {
                    let c = g.at(cx, cy);
                    [c.0, c.1]
                }),
                background_explained: found.background_explained,
                regions: found
                    .candidates
                    .iter()
                    .map(|c| {
                        let r = &c.region;
                        DebugRegion {
                            bbox: r.bbox,
                            area: r.pixels,
                            centroid: [r.centroid.0, r.centroid.1],
                            placed: r.placed.map(|p| [p.0, p.1]),
                            placement: c.placement.as_ref().map(|p| p.describe()),
                            colour: r.colour,
                            mean_flow: [r.mean_flow.0, r.mean_flow.1],
                            aligned: r.aligned.map(|m| [m.0, m.1]),
                            speed: r.speed,
                            residual_flow: c.residuals.map(|x| x.0),
                            residual_background: c.residuals.map(|x| x.1),
                            residual_ratio: c.ratio().filter(|r| r.is_finite()),
                            accepted: c.accepted,
                            reason: c.reason.clone(),
                            // Accepted regions reach the tracker in the same order.
                            track: if c.accepted {
                                assigned.next().cloned().flatten()
                            } else {
                                None
                            },
                        }
                    })
                    .collect(),
                held: tracker.held.clone(),
            });
        }
    }
    Ok(TrackRun {
        tracks: Tracks {
            ms_per_frame: Some(busy.as_secs_f64() * 1e3 / count.max(1) as f64),
            objects: objects
                .into_iter()
                .map(|(id, frames)| ObjectTrack { id, frames })
                .collect(),
            background_flow: still.and_then(|s| s.summary()),
        },
        debug,
    })
}

/// The margin (px) around each object, beyond its radius, that is not counted as static in the
/// background-flow metric: the camera's blur spreads a mover over a few pixels.
pub const STATIC_MARGIN_PX: f64 = 6.0;

/// The background-flow magnitude of a folder of flows against a truth.
pub fn background_flow(files: &[PathBuf], truth: &Truth) -> Result<Option<BackgroundFlow>> {
    let mut s = StaticFlow::new(truth, STATIC_MARGIN_PX)?;
    for (n, f) in files.iter().enumerate() {
        s.add(n, &io::read_flow(f)?)?;
    }
    Ok(s.summary())
}
