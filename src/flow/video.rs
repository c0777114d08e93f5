//! MMS on a video (Notes S13–S15 at the camera's rate): the flows of consecutive pairs, each
//! doing only what the previous pair has not already done.
//!
//! - **Reuse**: frame n's feature encoding, computed as the second frame of pair (n − 1, n),
//!   is the first frame's of pair (n, n + 1): two encoder passes per pair instead of three.
//!   The arithmetic is the same (each image is encoded on its own), so the flow is the same
//!   to the last bit. A frame that is not the previous pair's second (another size, a skipped
//!   frame, other pixels) is encoded again.
//! - **Warm start** (RAFT on video): the previous pair's flow, carried forward along itself
//!   ([`super::warm`], its background settled on one motion first) and scaled by the ratio of
//!   the pairs' time gaps, starts the updates instead of zero or the coarse start.
//! - **Auto iterations**: the updates stop once an update's mean length falls below
//!   [`AUTO_STOP_PX`], at most the asked count.

use burn::prelude::*;

use super::infer::{LastFrame, Network, Predictor, Start};
use super::resample::resize_flow;
use super::scale::check_scale;
use super::warm::{forward_warp, settle_background};
use crate::error::{Error, Result};
use crate::imaging::resize::{downscale, resize_to, scaled_size};
use crate::types::{Flow, Image};

/// The mean update length (full-resolution pixels) below which `--iters auto` stops.
pub const AUTO_STOP_PX: f32 = 0.05;

/// What a video run may carry from one pair to the next.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VideoOptions {
    /// Reuse the first frame's features when it was the previous pair's second.
    pub reuse: bool,
    /// Start from the previous pair's flow, forward-warped.
    pub warm_start: bool,
    /// Stop the updates once one moves the flow less than this many pixels on average.
    pub stop_px: Option<f32>,
}

impl Default for VideoOptions {
    /// Reuse on (it changes nothing but the time), warm start and early stop off.
    fn default() -> Self {
        Self {
            reuse: true,
            warm_start: false,
            stop_px: None,
        }
    }
}

impl VideoOptions {
    /// Nothing carried over: every pair as `Predictor::predict` runs it alone.
    pub fn independent() -> Self {
        Self {
            reuse: false,
            warm_start: false,
            stop_px: None,
        }
    }
}

/// One pair of a video.
#[derive(Clone, Debug)]
pub struct VideoPair {
    pub flow: Flow,
    /// The network updates run (at the full level).
    pub iters: usize,
    /// Whether the first frame's features were reused.
    pub reused: bool,
    /// Whether the updates started from the previous pair's flow.
    pub warm: bool,
}

/// The state between the pairs of one video.
pub struct VideoFlow {
    opts: VideoOptions,
    scale: f64,
    /// The last frame at the network's size, and at half of it for the coarse start.
    full: Option<LastFrame>,
    coarse: Option<LastFrame>,
}

impl VideoFlow {
    /// A video whose frames the network sees at `scale` ∈ (0, 4] of their size (the flow is
    /// brought back to it, as `super::scale::predict_scaled` does).
    pub fn new(opts: VideoOptions, scale: f64) -> Result<Self> {
        check_scale(scale)?;
        if let Some(px) = opts.stop_px
            && !(px.is_finite() && px > 0.0)
        {
            return Err(Error::invalid(
                "auto iterations",
                format!("the stop threshold must be a positive number of pixels, got {px}"),
            ));
        }
        Ok(Self {
            opts,
            scale,
            full: None,
            coarse: None,
        })
    }

    /// Every pair on its own, at the frames' size: what `Predictor::predict` gives.
    pub fn independent() -> Self {
        Self {
            opts: VideoOptions::independent(),
            scale: 1.0,
            full: None,
            coarse: None,
        }
    }

    /// Forgets the last frame: the next pair starts afresh.
    pub fn reset(&mut self) {
        self.full = None;
        self.coarse = None;
    }

    /// The flow from `img1` to `img2` after at most `iters` updates and `predictor`'s
    /// refinement. `gap_ratio` is this pair's time gap over the previous pair's (1 for the
    /// frames of a file sequence): the warm start's motion is scaled by it.
    pub fn pair(
        &mut self,
        predictor: &Predictor,
        img1: &Image,
        img2: &Image,
        iters: usize,
        gap_ratio: f64,
    ) -> Result<VideoPair> {
        if !(gap_ratio.is_finite() && gap_ratio > 0.0) {
            return Err(Error::invalid(
                "gap ratio",
                format!("must be a positive number, got {gap_ratio}"),
            ));
        }
        let (_, h, w) = img1.shape();
        let (sh, sw) = scaled_size(h, w, self.scale);
        let resized;
        let (a, b) = if (sh, sw) == (h, w) {
            (img1, img2)
        } else {
            if img2.shape() != img1.shape() {
                return Err(Error::shape(
                    "second image",
                    format!("{w}x{h} (the first image)"),
                    format!("{}x{}", img2.width(), img2.height()),
                ));
            }
            resized = (resize_to(img1, sh, sw)?, resize_to(img2, sh, sw)?);
            (&resized.0, &resized.1)
        };
        let out = self.network_pair(predictor, a, b, iters, gap_ratio as f32)?;
        let flow = predictor.refined(a, b, out.flow)?;
        let flow = if (sh, sw) == (h, w) {
            flow
        } else {
            resize_flow(&flow, h, w)?
        };
        Ok(VideoPair { flow, ..out })
    }

    /// The network's flow at the network's size, reusing and warm-starting where allowed.
    fn network_pair(
        &mut self,
        predictor: &Predictor,
        a: &Image,
        b: &Image,
        iters: usize,
        gap_ratio: f32,
    ) -> Result<VideoPair> {
        let net = Network {
            model: &predictor.model,
            config: &predictor.config,
            device: &predictor.device,
        };
        let (h, w) = (a.height(), a.width());
        let last = self.full.take().filter(|l| l.is(a));
        let warm = match (&last, self.opts.warm_start) {
            (Some(l), true) => Some(warm_grid(&l.flow8, gap_ratio, &predictor.device)?),
            _ => None,
        };
        let coarse_start = warm.is_none()
            && predictor.coarse_start
            && h.min(w) >= 2 * predictor.config.min_side().max(16);
        let coarse = if coarse_start {
            let (ca, cb) = (downscale(a, 0.5)?, downscale(b, 0.5)?);
            let reuse = self.coarse.take().filter(|_| self.opts.reuse);
            let out = net.pair(&ca, &cb, iters, Start::Zero, reuse, None)?;
            self.coarse = Some(out.last);
            Some(resize_flow(&out.flow, h, w)?)
        } else {
            self.coarse = None;
            None
        };
        let was_warm = warm.is_some();
        let start = match (warm, &coarse) {
            (Some(grid), _) => Start::Grid(Box::new(grid)),
            (None, Some(f)) => Start::Flow(f),
            (None, None) => Start::Zero,
        };
        let reuse = last.filter(|_| self.opts.reuse);
        let out = net.pair(a, b, iters, start, reuse, self.opts.stop_px)?;
        let pair = VideoPair {
            flow: out.flow,
            iters: out.iters,
            reused: out.reused,
            warm: was_warm,
        };
        if self.opts.reuse || self.opts.warm_start {
            self.full = Some(out.last);
        }
        Ok(pair)
    }
}

/// The grid flow `flow8` (`[1, 2, h, w]`) carried one pair forward, scaled by `ratio`.
fn warm_grid(flow8: &Tensor<4>, ratio: f32, device: &Device) -> Result<Tensor<4>> {
    let [_, _, h, w] = flow8.dims();
    let data: Vec<f32> = flow8
        .clone()
        .into_data()
        .try_to_vec::<f32>()
        .map_err(|e| Error::invalid("previous flow", format!("{e:?}")))?;
    let (settled, background) = settle_background(&data, h, w);
    let warped = forward_warp(&settled, h, w, ratio, background);
    Ok(Tensor::<4>::from_data(
        TensorData::new(warped, [1, 2, h, w]),
        device,
    ))
}
