//! MMS over consecutive frames: the flow of every pair (n, n + 1) of a frame sequence, in order,
//! with the network's time per pair. The one loop behind `pins infer --frames`,
//! `pins track --frames` and the tracking experiments (Note S13).

use std::borrow::Cow;
use std::path::PathBuf;
use std::time::Instant;

use super::infer::Predictor;
use super::video::{VideoFlow, VideoOptions};
use crate::error::Result;
use crate::types::{Flow, Image};

/// The frames of a sequence, read on demand.
pub trait Frames {
    /// How many frames there are.
    fn count(&self) -> usize;
    /// Frames `n` and `n + 1`, of the same size.
    fn pair(&self, n: usize) -> Result<(Cow<'_, Image>, Cow<'_, Image>)>;
}

/// Image files in order, read pair by pair (a pair of two different sizes is an error naming
/// both files).
impl Frames for [PathBuf] {
    fn count(&self) -> usize {
        self.len()
    }

    fn pair(&self, n: usize) -> Result<(Cow<'_, Image>, Cow<'_, Image>)> {
        let (a, b) = crate::io::read_image_pair(&self[n], &self[n + 1])?;
        Ok((Cow::Owned(a), Cow::Owned(b)))
    }
}

/// Frames already in memory.
impl Frames for [Image] {
    fn count(&self) -> usize {
        self.len()
    }

    fn pair(&self, n: usize) -> Result<(Cow<'_, Image>, Cow<'_, Image>)> {
        Ok((Cow::Borrowed(&self[n]), Cow::Borrowed(&self[n + 1])))
    }
}

/// The flow from frame `index` to frame `index + 1`.
#[derive(Clone, Debug)]
pub struct PairFlow {
    pub index: usize,
    pub flow: Flow,
    /// Milliseconds the network took (reading the frames excluded).
    pub ms: f64,
    /// The updates run (fewer than asked where `--iters auto` stopped them).
    pub iters: usize,
}

/// The flows of every consecutive pair of `frames` after `iters` refinements, lazily and in
/// order, each pair on its own: the first error ends the sequence for a caller that stops at
/// it.
pub fn pair_flows<'a, F: Frames + ?Sized>(
    predictor: &'a Predictor,
    frames: &'a F,
    iters: usize,
) -> impl Iterator<Item = Result<PairFlow>> + 'a {
    video_pairs(predictor, frames, iters, VideoFlow::independent())
}

/// As `pair_flows`, with the network run at `scale` ∈ (0, 4] of the frames' size and the flow
/// brought back to it (`super::scale`), and what carries from pair to pair (`super::video`);
/// the time includes the resampling. A scale out of range or bad options are refused before
/// any frame is read.
pub fn pair_flows_scaled<'a, F: Frames + ?Sized>(
    predictor: &'a Predictor,
    frames: &'a F,
    iters: usize,
    scale: f64,
    video: VideoOptions,
) -> Result<impl Iterator<Item = Result<PairFlow>> + 'a> {
    Ok(video_pairs(
        predictor,
        frames,
        iters,
        VideoFlow::new(video, scale)?,
    ))
}

/// The pairs of `frames` in order through one video state.
fn video_pairs<'a, F: Frames + ?Sized>(
    predictor: &'a Predictor,
    frames: &'a F,
    iters: usize,
    mut state: VideoFlow,
) -> impl Iterator<Item = Result<PairFlow>> + 'a {
    (0..frames.count().saturating_sub(1)).map(move |index| {
        let (a, b) = frames.pair(index)?;
        let started = Instant::now();
        let pair = state.pair(predictor, &a, &b, iters, 1.0)?;
        Ok(PairFlow {
            index,
            flow: pair.flow,
            ms: started.elapsed().as_secs_f64() * 1e3,
            iters: pair.iters,
        })
    })
}
