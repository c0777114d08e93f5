//! What a run trains and validates on (Note S11's data): a folder of pairs with ground-truth
//! flow, split into training pairs and a held-out tail, or a stream of pairs made on the fly
//! ([`super::stream`]) with its own fixed validation pairs.

use std::path::Path;
use std::sync::Arc;

use rand::RngExt;

use super::config::TrainConfig;
use super::stream::{Stream, is_stream_file};
use crate::error::{Error, Result};
use crate::flow::data::{DataFingerprint, FlowDataset};
use crate::rng;
use crate::types::{Flow, Image};

/// The data of a run (`--data`), ready to train on, with its identity.
#[derive(Clone)]
pub struct TrainData {
    /// What identifies the data, kept in checkpoints and weights' stamps.
    pub fingerprint: DataFingerprint,
    pairs: Pairs,
}

#[derive(Clone)]
enum Pairs {
    /// A folder's training pairs and its held-out tail (the last `val_fraction`).
    Folder {
        train: FlowDataset,
        val: FlowDataset,
    },
    Stream(Arc<Stream>),
}

impl TrainData {
    /// Opens `--data`, a stream file (`.json`) or a folder of pairs: a folder fingerprinted,
    /// checked for known flow and split; every source's frames checked against the crop.
    pub fn open(path: &Path, config: &TrainConfig) -> Result<Self> {
        let (fingerprint, pairs) = if is_stream_file(path) {
            let stream = Stream::open(path)?;
            (
                stream.fingerprint().clone(),
                Pairs::Stream(Arc::new(stream)),
            )
        } else {
            let set = FlowDataset::open(path)?;
            let fingerprint = set.fingerprint()?;
            set.check_has_known_flow()?;
            let (train, val) = set.split(config.val_fraction);
            (fingerprint, Pairs::Folder { train, val })
        };
        // Every source's frames against its crop (a stream's source may have its own).
        let checks: Vec<((usize, usize), [usize; 2])> = match &pairs {
            Pairs::Folder { train, .. } => {
                let (a, _, _) = train.load(0)?;
                vec![((a.height(), a.width()), config.crop)]
            }
            Pairs::Stream(s) => s.frames_and_crops(config.crop),
        };
        for ((h, w), crop) in checks {
            if h < crop[0] || w < crop[1] {
                return Err(Error::invalid(
                    "train.crop",
                    format!(
                        "{crop:?} is larger than the {h}x{w} images of {}",
                        path.display()
                    ),
                ));
            }
        }
        Ok(Self { fingerprint, pairs })
    }

    /// Training pair `slot` of step `step`'s batch, drawn with `r`, and the crop it is cut to:
    /// a random training pair of a folder (the run's crop), or the stream's pair of that step
    /// and slot, from a source of crop `within` when given (the batch's other slots).
    pub fn train_pair(
        &self,
        config: &TrainConfig,
        step: usize,
        slot: usize,
        within: Option<[usize; 2]>,
        r: &mut rng::Rng,
    ) -> Result<(Image, Image, Flow, [usize; 2])> {
        match &self.pairs {
            Pairs::Folder { train, .. } => {
                let i = r.random_range(0..train.pairs.len());
                let (a, b, f) = train.load(i)?;
                Ok((a, b, f, config.crop))
            }
            Pairs::Stream(s) => s.train_pair(step, slot, config.batch_size, config.crop, within, r),
        }
    }

    /// The number of validation pairs scored (at most `max`, at least one).
    pub fn val_count(&self, max: usize) -> usize {
        match &self.pairs {
            Pairs::Folder { val, .. } => val.pairs.len().min(max.max(1)),
            Pairs::Stream(_) => max.max(1),
        }
    }

    /// Validation pair `j` of the `n` scored.
    pub fn val_pair(&self, j: usize, n: usize) -> Result<(Image, Image, Flow)> {
        match &self.pairs {
            Pairs::Folder { val, .. } => val.load(j),
            Pairs::Stream(s) => s.val_pair(j, n),
        }
    }
}
