//! Inference: load exported weights (no training stack) and estimate the flow between two
//! images of any size — padded to a multiple of 8 by edge replication and cropped back.

use std::path::Path;

use burn::prelude::*;

use super::data::image_tensor;
use super::model::{InputPadder, Mms, MmsConfig};
use super::refine::{Refine, RefineConfig, refine};
use super::weights;
use crate::error::{Error, Result};
use crate::types::{Flow, Image};

/// The shipped weights, compiled into the binary and named by `--weights NAME` (see the README
/// for the commands that made them): `mms-small-real` (stage 5: photographic, large-motion,
/// still- and plain-background data; the best flow on real images, so `default` for the flow
/// commands) and `mms-small` (stage 3, on the generator's chairs; the tracker's weights, whose
/// small movers' flow the tracking clips measured better).
pub const BUILTIN_WEIGHTS: [(&str, &str, &[u8]); 2] = [
    (
        "mms-small-real",
        "datasets/weights/mms-small-real.safetensors",
        include_bytes!("../../datasets/weights/mms-small-real.safetensors"),
    ),
    (
        "mms-small",
        "datasets/weights/mms-small.safetensors",
        include_bytes!("../../datasets/weights/mms-small.safetensors"),
    ),
];

/// What `--weights default` names.
pub const DEFAULT_WEIGHTS: &str = "mms-small-real";

/// The weights the tracker uses by default (`pins track --frames`, `pins live`, track
/// experiments).
pub const TRACK_WEIGHTS: &str = "mms-small";

/// Whether `name` is `default` or a built-in weights name rather than a file.
pub fn is_builtin(name: &str) -> bool {
    name == "default" || BUILTIN_WEIGHTS.iter().any(|(n, _, _)| *n == name)
}

/// A loaded network ready to run, and the refinement its flow gets (variational by default:
/// see [`super::refine`]).
pub struct Predictor {
    pub model: Mms,
    pub config: MmsConfig,
    pub device: Device,
    pub refine: Option<RefineConfig>,
}

impl Predictor {
    /// Loads a weights file, or built-in weights by name (`default`, `mms-small-real`,
    /// `mms-small`), onto the CPU.
    pub fn load(path: &str) -> Result<Self> {
        Self::load_on(path, Device::flex())
    }

    /// Loads a weights file onto `device`.
    pub fn load_on(path: &str, device: Device) -> Result<Self> {
        let name = if path == "default" {
            DEFAULT_WEIGHTS
        } else {
            path
        };
        let builtin = BUILTIN_WEIGHTS.iter().find(|(n, _, _)| *n == name);
        let (model, config) = if let Some((_, file, bytes)) = builtin {
            weights::from_bytes(bytes, Path::new(file), &device)?
        } else {
            weights::load(Path::new(path), &device)?
        };
        Ok(Self {
            model,
            config,
            device,
            refine: Refine::default().config(),
        })
    }

    /// The same predictor with the refinement `refine`.
    pub fn with_refine(mut self, refine: &Refine) -> Self {
        self.refine = refine.config();
        self
    }

    /// The flow from `img1` to `img2` after `iters` network iterations and the refinement.
    pub fn predict(&self, img1: &Image, img2: &Image, iters: usize) -> Result<Flow> {
        let flow = self.predict_network(img1, img2, iters)?;
        self.refined(img1, img2, flow)
    }

    /// The network's own flow, without the refinement.
    pub fn predict_network(&self, img1: &Image, img2: &Image, iters: usize) -> Result<Flow> {
        predict_flow(&self.model, &self.config, img1, img2, iters, &self.device)
    }

    /// `flow` after this predictor's refinement (itself when there is none).
    pub fn refined(&self, img1: &Image, img2: &Image, flow: Flow) -> Result<Flow> {
        match &self.refine {
            Some(cfg) => refine(img1, img2, &flow, cfg),
            None => Ok(flow),
        }
    }
}

/// Runs `model` on one pair. Images must have the same size; grey images are repeated to RGB.
pub fn predict_flow(
    model: &Mms,
    config: &MmsConfig,
    img1: &Image,
    img2: &Image,
    iters: usize,
    device: &Device,
) -> Result<Flow> {
    if (img1.height(), img1.width()) != (img2.height(), img2.width()) {
        return Err(Error::shape(
            "second image",
            format!("{}x{} (the first image)", img1.width(), img1.height()),
            format!("{}x{}", img2.width(), img2.height()),
        ));
    }
    if iters == 0 || iters > 256 {
        return Err(Error::invalid(
            "--iters",
            format!("must be 1..=256, got {iters}"),
        ));
    }
    img1.check_nonempty("first image")?;
    img1.check_finite("first image")?;
    img2.check_finite("second image")?;
    let (h, w) = (img1.height(), img1.width());
    let padder = InputPadder::new(h, w, config.min_side());
    let a = padder.pad(image_tensor(img1, device));
    let b = padder.pad(image_tensor(img2, device));
    let pred = model
        .forward(a, b, iters, false)
        .pop()
        .ok_or_else(|| Error::invalid("model", "no prediction"))?;
    let flow = padder.unpad(pred); // [1, 2, H, W]
    let data: Vec<f32> = flow
        .into_data()
        .try_to_vec::<f32>()
        .map_err(|e| Error::invalid("model output", format!("{e:?}")))?;
    let out = Flow::from_vec(h, w, data)?;
    if out.data().iter().any(|v| !v.is_finite()) {
        return Err(Error::invalid(
            "model output",
            "the network produced non-finite flow",
        ));
    }
    Ok(out)
}
