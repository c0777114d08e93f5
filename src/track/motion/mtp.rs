//! One object's motion trajectory predictor (Note S13, Fig. S11): each frame's region feeds
//! Kalman filters on position (constant velocity), speed and the sine and cosine of the
//! direction; the smoothed speed and direction over the last L frames are fitted by weighted
//! polynomials of order n and extrapolated to the requested horizons.

use std::collections::VecDeque;

use super::forecast_score::ForecastScores;
use super::kalman::{ConstantVelocity, RandomWalk};
use super::predict::{fit_motion, supported_order};
use super::step::{Step, along};
use crate::error::{Error, Result};
use crate::track::detect::roi::Region;

/// Measured frames before a track's forecasts enter `Method::Select`'s record (the
/// tracker's confirmation window).
const SETTLED: usize = 5;

/// How the future path is predicted.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// The paper's predictor: weighted polynomial fits of speed and direction (Eqs. S20–S23).
    Poly,
    /// The baseline: the position Kalman filter's velocity held constant.
    ConstantVelocity,
    /// For each horizon k, whichever of the two forecast this track better over its own
    /// recent past (`track::motion::forecast_score`): the polynomial fit until both have been
    /// checked a few times at that horizon, and unless the constant velocity's record is
    /// clearly better (`forecast_score::SWITCH_RATIO`). The fit wins on steadily turning
    /// paths, the constant velocity where the direction oscillates within the window.
    Select,
}

/// Predictor settings (the paper's defaults: L = 30, n = 2).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MtpConfig {
    /// `null` (the default): settled by `TrackConfig::resolved`, `Method::Select` where the samples are
    /// measured on the frames (an estimated flow's pipeline, whose forecasts 30 frames ahead
    /// it took closer on 30 of 44 clips and further on 1, tracking unchanged), the paper's
    /// `Method::Poly` otherwise.
    pub method: Option<Method>,
    pub window: usize,
    pub order: usize,
    /// A fit of order k waits for min(L, this × k + 1) samples in its window, with a lower
    /// order until then (`predict::supported_order`): with 5, a new track's forecasts are a
    /// constant speed and direction for its first 5 samples and linear from 6 to 10; with 1,
    /// the highest order the samples determine (the paper's fit). `null` (the default):
    /// settled by `TrackConfig::resolved`, `SAMPLES_PER_ORDER_MEASURED` where the samples are measured on
    /// the frames (aligned motions, placed centres: an estimated flow's pipeline), whose
    /// noise a quadratic through a new track's few samples extrapolates hundreds of pixels,
    /// and 1 for a given flow's own samples, exact enough to fit at once.
    pub samples_per_order: Option<usize>,
    /// The fitted trend of speed and direction is followed for this many times the window's
    /// time span past the last sample, and the velocity held from there
    /// (`MotionFit::hold_after`): a young track's fit over 10 frames is not extrapolated 30.
    /// 0 follows it all the way (Eq. S22's). `null` (the default): settled by `TrackConfig::resolved`,
    /// `TREND_REACH_MEASURED` where the samples are measured on the frames, 0 otherwise.
    pub trend_reach: Option<f64>,
    /// Kalman process and measurement noise for position (px²) and for speed and direction.
    pub position_q: f64,
    pub position_r: f64,
    pub motion_q: f64,
    pub motion_r: f64,
    /// The measurement noise of the region's flow velocity in the position filter when the
    /// centroid was placed on the frame (`Region::placed`, px²/frame²): the placed centre is
    /// the object's, and an estimated flow on a small mover is 1.3–1.5 px/frame RMS off, so
    /// the centroids' displacement gets a say in the velocity.
    pub placed_motion_r: f64,
    /// Where the speed and direction samples of the fit come from.
    pub motion_source: MotionSource,
    /// The measurement noise (px²/frame²) of the motion the frames confirm (`Region::aligned`)
    /// as the velocity of the *forecasts'* position filter, a twin of the tracking filter
    /// whose velocity is fed by that motion instead of the region's flow (an aligned motion
    /// more than `ALIGNED_GATE` standard deviations off the filter's velocity is left out).
    /// The forecasts start from its centre; the reported centre, the association's look-ahead
    /// and the velocity gate keep the tracking filter's, whose velocity is what the
    /// detections' flow is compared with. An estimated flow that gives a small mover half its
    /// motion holds the tracking filter's centre back behind the object (experiments/results/tracking_log.md).
    /// While the object is unseen the twin takes the tracking filter's state. `null` starts
    /// the forecasts from the tracking filter's centre. Without aligned motions (a given
    /// flow's own regions) the two filters are the same.
    pub aligned_motion_r: Option<f64>,
}

/// Innovation gate of the aligned motion in the forecasts' filter: the squared innovations of
/// its two components, each over its variance, may sum to at most this squared (χ² with 2
/// degrees of freedom: 99 % of true measurements pass).
pub const ALIGNED_GATE: f64 = 3.0;

/// The samples of the speed and direction fits (Eqs. S20–S21).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MotionSource {
    /// The filter's velocity where the region was placed on the frame (`Region::placed`),
    /// the region's flow elsewhere: an exact flow's samples stay the paper's.
    #[default]
    Auto,
    /// The region's flow (the paper's).
    Flow,
    /// The position filter's velocity, which fuses the centroids with the flow: where the
    /// centroids are the objects' own (placed on the frame) and the flow underestimates a
    /// small mover, the centroids' displacement corrects its speed.
    Filter,
}

impl Default for MtpConfig {
    fn default() -> Self {
        Self {
            method: None,
            window: 30,
            order: 2,
            samples_per_order: None,
            trend_reach: None,
            position_q: 0.5,
            position_r: 1.0,
            motion_q: 0.05,
            motion_r: 0.25,
            placed_motion_r: 1.0,
            motion_source: MotionSource::Auto,
            aligned_motion_r: Some(ALIGNED_MOTION_R),
        }
    }
}

/// The aligned motion's measurement noise in the forecasts' filter (`MtpConfig::
/// aligned_motion_r`, px²/frame²): the flow's own in the tracking filter (`motion_r`), as the
/// aligned motion is the more accurate of the two on small movers (experiments/results/tracking_log.md).
pub const ALIGNED_MOTION_R: f64 = 0.25;

/// Samples per order of the fits whose samples are measured on the frames (`MtpConfig::
/// samples_per_order`): over the 40 tracking clips on MMS flow, 5 took the forecasts 15 and 30
/// frames ahead closer on 27 and 34 clips and further on 4 and 4 (experiments/results/tracking_log.md).
pub const SAMPLES_PER_ORDER_MEASURED: usize = 5;

/// The trend's reach where the samples are measured on the frames (`MtpConfig::trend_reach`):
/// over the 44 tracking clips on MMS flow, 1 took the forecasts 30 frames ahead closer on 27
/// clips and further on 5, all spirals (experiments/results/tracking_log.md).
pub const TREND_REACH_MEASURED: f64 = 1.0;

impl MtpConfig {
    pub fn validate(&self) -> Result<()> {
        if let Some(n) = self.samples_per_order
            && !(1..=10_000).contains(&n)
        {
            return Err(Error::invalid(
                "mtp.samples_per_order",
                format!("must be 1..=10000, got {n}"),
            ));
        }
        if let Some(r) = self.trend_reach
            && !(r.is_finite() && r >= 0.0)
        {
            return Err(Error::invalid(
                "mtp.trend_reach",
                format!("must be finite and >= 0, got {r}"),
            ));
        }
        if let Some(r) = self.aligned_motion_r
            && !(r.is_finite() && r > 0.0)
        {
            return Err(Error::invalid(
                "mtp.aligned_motion_r",
                format!("must be finite and > 0, or null, got {r}"),
            ));
        }
        if self.window == 0 || self.window > 10_000 || self.order > 6 {
            return Err(Error::invalid(
                "mtp",
                format!(
                    "window must be 1..=10000 and order 0..=6, got {} and {}",
                    self.window, self.order
                ),
            ));
        }
        for (n, v) in [
            ("position_q", self.position_q),
            ("position_r", self.position_r),
            ("motion_q", self.motion_q),
            ("motion_r", self.motion_r),
            ("placed_motion_r", self.placed_motion_r),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::invalid(
                    format!("mtp.{n}"),
                    format!("must be finite and >= 0, got {v}"),
                ));
            }
        }
        Ok(())
    }
}

/// The filtered state after one frame and its predictions.
#[derive(Clone, Debug, PartialEq)]
pub struct Estimate {
    pub frame: usize,
    pub centroid: (f64, f64),
    pub speed: f64,
    pub direction: Option<f64>,
    /// Predicted centroids at 1…max horizon frames ahead.
    pub path: Vec<(f64, f64)>,
    /// Where the association looks for the object next frame: the path's first point, but for
    /// `Method::Select` the fit's (its choice per horizon serves the forecasts; gating on
    /// whichever won one frame ahead lately cost ID switches).
    pub next: (f64, f64),
}

/// The per-object predictor.
pub struct Mtp {
    config: MtpConfig,
    /// The tracking filter: the reported centre and the velocity the association gates on.
    x: ConstantVelocity,
    y: ConstantVelocity,
    /// The forecasts' filter (`MtpConfig::aligned_motion_r`).
    ahead_x: ConstantVelocity,
    ahead_y: ConstantVelocity,
    speed: RandomWalk,
    sin: RandomWalk,
    cos: RandomWalk,
    history: VecDeque<(f64, f64, Option<f64>)>,
    /// The forecasts' record for `Method::Select`.
    scores: ForecastScores,
    /// The time of the last step (stream frames).
    last_t: Option<f64>,
}

impl Mtp {
    pub fn new(config: MtpConfig) -> Result<Self> {
        config.validate()?;
        Ok(Self {
            x: ConstantVelocity::new(config.position_q, config.position_r),
            y: ConstantVelocity::new(config.position_q, config.position_r),
            ahead_x: ConstantVelocity::new(config.position_q, config.position_r),
            ahead_y: ConstantVelocity::new(config.position_q, config.position_r),
            speed: RandomWalk::new(config.motion_q, config.motion_r),
            sin: RandomWalk::new(config.motion_q, config.motion_r),
            cos: RandomWalk::new(config.motion_q, config.motion_r),
            history: VecDeque::new(),
            scores: ForecastScores::new(2),
            last_t: None,
            config,
        })
    }

    /// The position filter's velocity (px/frame).
    pub fn velocity(&self) -> (f64, f64) {
        (self.x.x[1], self.y.x[1])
    }

    /// Feeds frame `frame`'s region (or `None` when the object was not seen: the filters coast)
    /// and predicts `horizon` frames ahead.
    pub fn step(
        &mut self,
        frame: usize,
        region: Option<&Region>,
        horizon: usize,
    ) -> Result<Estimate> {
        self.step_at(Step::every(frame), region, horizon)
    }

    /// `step` on a stream processed at uneven gaps: the filters advance by the time since the
    /// last step, the region's motion is per stream frame (its flow over `step.span`, divided
    /// by it), the forecasts are 1 … `horizon` stream frames ahead and the association's look
    /// `step.span` ahead, where the next processed frame is.
    pub fn step_at(
        &mut self,
        step: Step,
        region: Option<&Region>,
        horizon: usize,
    ) -> Result<Estimate> {
        let frame = step.frame();
        let dt = match self.last_t {
            Some(last) if step.t > last => step.t - last,
            Some(last) => {
                return Err(Error::invalid(
                    "tracking step",
                    format!("time must increase, got {} after {last}", step.t),
                ));
            }
            None => 1.0,
        };
        self.last_t = Some(step.t);
        for f in [
            &mut self.x,
            &mut self.y,
            &mut self.ahead_x,
            &mut self.ahead_y,
        ] {
            f.predict_by(dt);
        }
        let (speed, direction) = match region {
            Some(r) => {
                let (cx, cy) = r.placed.unwrap_or(r.centroid);
                self.x.update(cx);
                self.y.update(cy);
                self.ahead_x.update(cx);
                self.ahead_y.update(cy);
                // The region's flow is the object's displacement to the next frame.
                let vr = match r.placed {
                    Some(_) => self.config.placed_motion_r,
                    None => self.config.motion_r,
                };
                let flow_velocity = r.direction.map(|d| (r.speed * d.cos(), r.speed * d.sin()));
                if let Some((u, v)) = flow_velocity {
                    self.x.update_velocity(u, vr);
                    self.y.update_velocity(v, vr);
                }
                match (r.aligned, self.config.aligned_motion_r) {
                    (Some((u, v)), Some(ra)) => {
                        let (fx, fy) = (&mut self.ahead_x, &mut self.ahead_y);
                        let innovation = (u - fx.x[1]).powi(2) / (fx.p[1][1] + ra)
                            + (v - fy.x[1]).powi(2) / (fy.p[1][1] + ra);
                        if innovation <= ALIGNED_GATE * ALIGNED_GATE {
                            fx.update_velocity(u, ra);
                            fy.update_velocity(v, ra);
                        }
                    }
                    _ => {
                        if let Some((u, v)) = flow_velocity {
                            self.ahead_x.update_velocity(u, vr);
                            self.ahead_y.update_velocity(v, vr);
                        }
                    }
                }
                let filter = match self.config.motion_source {
                    MotionSource::Auto => r.placed.is_some(),
                    MotionSource::Flow => false,
                    MotionSource::Filter => true,
                };
                // The motion the frames confirm (`Region::aligned`) comes first: it measures
                // the object's own displacement, where the flow and the filter fed by it
                // fall short on a small mover.
                let (speed, direction) = match (r.aligned, filter) {
                    (Some((u, v)), _) => {
                        let s = u.hypot(v);
                        (s, (s > 1e-9).then(|| v.atan2(u)))
                    }
                    (None, false) => (r.speed, r.direction),
                    (None, true) => {
                        let (vx, vy) = self.velocity();
                        let s = vx.hypot(vy);
                        (s, (s > 1e-9).then(|| vy.atan2(vx)))
                    }
                };
                let s = self.speed.step_by(speed, dt);
                let d = direction.map(|d| {
                    let (sn, cs) = (self.sin.step_by(d.sin(), dt), self.cos.step_by(d.cos(), dt));
                    sn.atan2(cs)
                });
                (s, d)
            }
            None => {
                // Unseen, the twin takes the tracking filter's state: coasting on an aligned
                // velocity that one bad alignment set drifts off (experiments/results/tracking_log.md).
                self.ahead_x = self.x.clone();
                self.ahead_y = self.y.clone();
                (self.speed.step_by(f64::NAN, dt), None)
            }
        };
        // The flow at frame n is the motion over [n, n + span]: its time is the middle.
        self.history
            .push_back((step.t + 0.5 * step.span, speed, direction));
        while self.history.len() > self.config.window {
            self.history.pop_front();
        }
        let centroid = (self.x.x[0], self.y.x[0]);
        // Where the forecasts start (`MtpConfig::aligned_motion_r`).
        let start = match self.config.aligned_motion_r {
            Some(_) => (self.ahead_x.x[0], self.ahead_y.x[0]),
            None => centroid,
        };
        // The paths reach the next processed frame too (`step.span` ahead): the association's.
        let reach = horizon.max(step.span.ceil() as usize);
        let poly = || -> Result<Vec<(f64, f64)>> {
            let samples: Vec<_> = self.history.iter().copied().collect();
            let order = supported_order(
                self.config.order,
                samples.len(),
                self.config.window,
                self.config.samples_per_order.unwrap_or(1),
            );
            let mut fit = fit_motion(&samples, order)?;
            fit.now = step.t;
            fit.hold_after = self
                .config
                .trend_reach
                .filter(|&r| r > 0.0)
                .map(|r| r * fit.span);
            Ok(fit.extrapolate(start, reach))
        };
        let (vx, vy) = (self.x.x[1], self.y.x[1]);
        let constant = || -> Vec<(f64, f64)> {
            (1..=reach)
                .map(|k| (start.0 + vx * k as f64, start.1 + vy * k as f64))
                .collect()
        };
        let mut next = None;
        let mut path = match self.config.method.unwrap_or(Method::Poly) {
            Method::Poly => poly()?,
            Method::ConstantVelocity => constant(),
            Method::Select => {
                let mut candidates = [poly()?, constant()];
                next = Some(along(start, &candidates[0], step.span));
                for c in &mut candidates {
                    c.truncate(horizon);
                }
                // Only a measured position checks the past forecasts; a coasting centre is
                // itself a forecast.
                if region.is_some() {
                    self.scores.check(frame, start);
                }
                let path = self.scores.choose(&candidates);
                // A track's first forecasts (a fit of a few samples, a velocity the filter
                // has barely measured) say nothing of how either predictor does later.
                let measured = self.history.iter().filter(|s| s.1.is_finite()).count();
                if measured >= SETTLED {
                    self.scores.record(frame, candidates);
                }
                path
            }
        };
        if path.iter().any(|p| !p.0.is_finite() || !p.1.is_finite())
            || !(centroid.0.is_finite() && start.0.is_finite())
        {
            return Err(Error::invalid(
                "trajectory",
                format!("prediction became non-finite at frame {frame}"),
            ));
        }
        // The association looks from the tracking filter's centre.
        let p = next.unwrap_or_else(|| along(start, &path, step.span));
        let next = (p.0 - start.0 + centroid.0, p.1 - start.1 + centroid.1);
        path.truncate(horizon);
        Ok(Estimate {
            frame,
            centroid,
            speed,
            direction,
            path,
            next,
        })
    }
}

#[cfg(test)]
mod tests;
