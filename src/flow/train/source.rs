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
        let (h, w) = match &pairs {
            Pairs::Folder { train, .. } => {
                let (a, _, _) = train.load(0)?;
                (a.height(), a.width())
            }
            Pairs::Stream(s) => s.smallest_frame(),
        };
        if h < config.crop[0] || w < config.crop[1] {
            return Err(Error::invalid(
                "train.crop",
                format!(
                    "{:?} is larger than the {h}x{w} images of {}",
                    config.crop,
                    path.display()
                ),
            ));
        }
        Ok(Self { fingerprint, pairs })
    }

    /// Training pair `slot` of step `step`'s batch, drawn with `r`: a random training pair of
    /// a folder, or the stream's pair of that step and slot.
    pub fn train_pair(
        &self,
        config: &TrainConfig,
        step: usize,
        slot: usize,
        r: &mut rng::Rng,
    ) -> Result<(Image, Image, Flow)> {
        match &self.pairs {
            Pairs::Folder { train, .. } => {
                let i = r.random_range(0..train.pairs.len());
                train.load(i)
            }
            Pairs::Stream(s) => s.train_pair(step, slot, config.batch_size, r),
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
