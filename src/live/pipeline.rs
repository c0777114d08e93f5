//! The live pipeline, one frame at a time: stitch (with a calibration) → downscale → MMS flow
//! from the previous processed frame → tracker → one JSON line. The line of a flow is that of
//! its first frame (as in `pins track`: the flow of frame n is its motion to frame n + 1), and
//! is written once frame n + 1 has arrived. Velocities are in pixels per second of the frames'
//! own time stamps (the camera's when it sends them, the arrival times otherwise).

use std::collections::BTreeMap;
use std::time::Instant;

use serde::Serialize;

use super::clock::{Stamp, StreamClock};
use super::reader::{Counts, Frame};
use super::tracking::{LiveTracker, Object};
use crate::error::Result;
use crate::flow::infer::Predictor;
use crate::flow::video::{VideoFlow, VideoOptions};
use crate::imaging::resize::downscale;
use crate::track::detect::photometric::{GreyFrame, GreyPair};
use crate::track::run::TrackOptions;
use crate::types::{Flow, Image};
use crate::wide::Stitcher;

/// Settings of the pipeline.
pub struct PipelineConfig {
    /// Downscale factor in (0, 1] of the (stitched) frames: tracks are in these pixels.
    pub scale: f64,
    /// The multiple of the downscaled frame's size that MMS runs at (`flow::scale`,
    /// `TrackConfig::flow.scale`), the flow brought back to it; `None`: the tracker's default
    /// for the frame's width (`track::config::track_scale`).
    pub flow_scale: Option<f64>,
    pub iters: usize,
    /// What carries from pair to pair (`flow::video`): feature reuse, warm start, early stop.
    pub video: VideoOptions,
    pub stitcher: Option<Stitcher>,
    pub track: TrackOptions,
}

/// One processed frame, one line of `tracks.jsonl`.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Line {
    /// Processed-frame index (the first frame of the flow).
    pub frame: usize,
    /// The received frame's sequence number.
    pub seq: u64,
    pub timestamp_s: f64,
    /// Frames received whole, dropped (replaced before processing) and skipped as bad so far.
    /// Predictions are keyed by stream frames ahead, velocities in pixels per second, whatever
    /// number of frames the pipeline dropped between two processed ones.
    pub received: u64,
    pub dropped: u64,
    pub bad: u64,
    pub objects: Vec<LineObject>,
    pub ms: Stages,
}

/// One object in a line.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct LineObject {
    pub id: usize,
    pub centroid: [f64; 2],
    /// Pixels per second.
    pub velocity: [f64; 2],
    pub predicted: BTreeMap<String, [f64; 2]>,
}

/// Milliseconds per stage for the frame that completed the flow, and its latency from arrival
/// to this line.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct Stages {
    pub prepare: f64,
    pub flow: f64,
    pub track: f64,
    pub latency: f64,
}

/// The state between frames.
pub struct Pipeline {
    predictor: Predictor,
    cfg: PipelineConfig,
    tracker: LiveTracker,
    /// Made at the first pair of each frame size (the scale may follow the width).
    video: Option<VideoFlow>,
    /// The processed frames' times and spans in stream frames.
    clock: StreamClock,
    prev: Option<Prepared>,
    /// The time step of the last flow (s): the warm start scales its motion by the next one's
    /// ratio to it.
    last_dt: Option<f64>,
    /// Processed frames so far.
    count: usize,
    /// The last flow and the frame it starts from, for the browser view.
    pub last_flow: Option<(Image, Flow, Vec<Object>)>,
    /// Frames whose size changed from the previous one (the tracker restarted).
    pub size_changes: usize,
}

struct Prepared {
    image: Image,
    grey: GreyFrame,
    index: usize,
    seq: u64,
    /// The camera's clock (s), when it sent one.
    camera_s: Option<f64>,
    time_s: f64,
    received_s: f64,
}

impl Pipeline {
    pub fn new(predictor: Predictor, cfg: PipelineConfig) -> Result<Self> {
        let tracker = LiveTracker::new(cfg.track.clone())?;
        // Checked now, so a bad scale fails before the first frame.
        if let Some(s) = cfg.flow_scale {
            VideoFlow::new(cfg.video, s)?;
        }
        Ok(Self {
            predictor,
            cfg,
            tracker,
            video: None,
            clock: StreamClock::new(),
            prev: None,
            last_dt: None,
            count: 0,
            last_flow: None,
            size_changes: 0,
        })
    }

    /// Processes one frame; a line once there is a previous frame to pair it with.
    pub fn process(&mut self, f: &Frame, counts: Counts) -> Result<Option<Line>> {
        let t0 = Instant::now();
        let wide = match &self.cfg.stitcher {
            Some(s) => s.apply(&f.image)?,
            None => (*f.image).clone(),
        };
        let image = downscale(&wide, self.cfg.scale)?;
        let cur = Prepared {
            grey: GreyFrame::new(&image),
            image,
            index: self.count,
            seq: f.seq,
            camera_s: f.camera_s,
            time_s: f.camera_s.unwrap_or(f.received_s),
            received_s: f.received_s,
        };
        self.count += 1;
        let prepare = t0.elapsed().as_secs_f64() * 1e3;
        let Some(prev) = self.prev.take() else {
            self.prev = Some(cur);
            return Ok(None);
        };
        if prev.image.shape() != cur.image.shape() {
            // A new frame size (the camera was reconfigured): nothing carries over.
            self.size_changes += 1;
            self.tracker.reset()?;
            self.video = None;
            self.clock = StreamClock::new();
            self.last_dt = None;
            self.prev = Some(cur);
            return Ok(None);
        }
        let (dt, camera) = step_seconds(&prev, &cur);
        let stamp = |p: &Prepared| Stamp {
            seq: p.seq,
            time_s: p.time_s,
            camera,
        };
        // Where this pair lies on the stream: the tracker's time step and its flow's span.
        let step = self.clock.step(stamp(&prev), stamp(&cur), dt)?;
        let period = self.clock.period().unwrap_or(dt / step.span);
        // Frames arrive at uneven gaps when the pipeline cannot keep up: the warm start's motion
        // is scaled by this gap over the last one.
        let gap_ratio = self
            .last_dt
            .map_or(1.0, |last| (dt / last).clamp(0.1, 10.0));
        self.last_dt = Some(dt);
        let t1 = Instant::now();
        let video = match &mut self.video {
            Some(v) => v,
            None => {
                let scale = self
                    .cfg
                    .flow_scale
                    .unwrap_or_else(|| crate::track::config::track_scale(cur.image.width()));
                self.video.insert(VideoFlow::new(self.cfg.video, scale)?)
            }
        };
        let flow = video
            .pair(
                &self.predictor,
                &prev.image,
                &cur.image,
                self.cfg.iters,
                gap_ratio,
            )?
            .flow;
        let flow_ms = t1.elapsed().as_secs_f64() * 1e3;
        let t2 = Instant::now();
        let pair = GreyPair::of(&prev.grey, &cur.grey);
        let objects = self.tracker.step(step, &flow, pair.as_ref())?;
        let track_ms = t2.elapsed().as_secs_f64() * 1e3;
        let line = Line {
            frame: prev.index,
            seq: prev.seq,
            timestamp_s: prev.time_s,
            received: counts.received,
            dropped: counts.dropped,
            bad: counts.bad,
            objects: objects
                .iter()
                .map(|o| LineObject {
                    id: o.id,
                    centroid: o.centroid,
                    velocity: [o.velocity[0] / period, o.velocity[1] / period],
                    predicted: o.predicted.clone(),
                })
                .collect(),
            ms: Stages {
                prepare,
                flow: flow_ms,
                track: track_ms,
                latency: f.arrived.elapsed().as_secs_f64() * 1e3,
            },
        };
        self.last_flow = Some((prev.image, flow, objects));
        self.prev = Some(cur);
        Ok(Some(line))
    }
}

/// The time between two processed frames: the camera's clock when it gives a plausible step
/// (0 < dt ≤ 10 s; then `true`), otherwise the arrival times, never below 1 ms.
fn step_seconds(a: &Prepared, b: &Prepared) -> (f64, bool) {
    if let (Some(ca), Some(cb)) = (a.camera_s, b.camera_s) {
        let cam = cb - ca;
        if cam > 0.0 && cam <= 10.0 {
            return (cam, true);
        }
    }
    let dt = b.received_s - a.received_s;
    (if dt.is_finite() { dt.max(1e-3) } else { 1e-3 }, false)
}
