//! The tracker of `pins track`, fed one flow at a time: the same detection (background model,
//! noise floor, photometric test) and the same multi-object tracker as
//! `track::run::track_sequence`, which only takes a whole sequence, so a live run can write each
//! frame's objects as soon as its flow exists.

use std::collections::BTreeMap;

use crate::error::Result;
use crate::track::detect::detect;
use crate::track::detect::photometric::GreyPair;
use crate::track::detect::split::Seed;
use crate::track::detect::still_background::StillBackground;
use crate::track::motion::step::Step;
use crate::track::run::TrackOptions;
use crate::track::tracker::multi::Tracker;
use crate::types::Flow;

/// One confirmed object after one frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Object {
    pub id: usize,
    pub centroid: [f64; 2],
    /// Pixels per stream frame (the region's flow over its span, filtered).
    pub velocity: [f64; 2],
    pub observed: bool,
    /// Horizon (stream frames, as a string) → predicted centroid.
    pub predicted: BTreeMap<String, [f64; 2]>,
    /// Predicted centroids 1 … max horizon stream frames ahead.
    pub path: Vec<[f64; 2]>,
}

/// The incremental tracker.
pub struct LiveTracker {
    tracker: Tracker,
    placer: Option<StillBackground>,
    opts: TrackOptions,
    max_h: usize,
}

impl LiveTracker {
    /// Checks the options as `track_sequence` does.
    pub fn new(opts: TrackOptions) -> Result<Self> {
        opts.validate()?;
        let max_h = opts.horizons.iter().copied().max().unwrap_or(1);
        Ok(Self {
            tracker: Tracker::new(opts.tracker.clone())?,
            placer: opts.detect.still_background()?,
            opts,
            max_h,
        })
    }

    /// Starts over (a new frame size): no track survives.
    pub fn reset(&mut self) -> Result<()> {
        self.tracker = Tracker::new(self.opts.tracker.clone())?;
        self.placer = self.opts.detect.still_background()?;
        Ok(())
    }

    /// Tracks the flow from the processed frame at `step.t` to the next, `step.span` stream
    /// frames later (`track::motion::step`); `pair` (the two frames) runs the photometric test.
    pub fn step(
        &mut self,
        step: Step,
        flow: &Flow,
        pair: Option<&GreyPair>,
    ) -> Result<Vec<Object>> {
        let o = &self.opts;
        let mut found = detect(flow, pair, o.threshold, o.noise_k, o.min_area, &o.detect)?;
        if let (Some(model), Some(pair)) = (self.placer.as_mut(), pair) {
            // A split part moves as its seed over this flow's span (divided back below).
            let seeds: Vec<Seed> = self
                .tracker
                .seeds()
                .into_iter()
                .map(|s| Seed {
                    velocity: (s.velocity.0 * step.span, s.velocity.1 * step.span),
                    ..s
                })
                .collect();
            found.place(model, pair.first_colour(), &seeds);
        }
        if let Some(pair) = pair {
            found.colour(pair.first_colour());
        }
        let dets: Vec<_> = found
            .accepted()
            .into_iter()
            .map(|d| d.per_frame(step.span))
            .collect();
        self.tracker.set_frame_size(flow.width(), flow.height());
        let out = self.tracker.step_at(step, &dets, self.max_h)?;
        Ok(out
            .into_iter()
            .map(|t| {
                let e = &t.estimate;
                let velocity = match e.direction {
                    Some(d) => [e.speed * d.cos(), e.speed * d.sin()],
                    None => [0.0, 0.0],
                };
                Object {
                    id: t.id,
                    centroid: [e.centroid.0, e.centroid.1],
                    velocity,
                    observed: t.observed,
                    predicted: o
                        .horizons
                        .iter()
                        .filter_map(|&h| e.path.get(h - 1).map(|p| (h.to_string(), [p.0, p.1])))
                        .collect(),
                    path: e.path.iter().map(|p| [p.0, p.1]).collect(),
                }
            })
            .collect())
    }
}
