//! Inference: load exported weights (no training stack) and estimate the flow between two
//! images of any size — padded to a multiple of 8 by edge replication and cropped back.

use std::path::Path;

use burn::prelude::*;

use super::data::image_tensor;
use super::model::{InputPadder, Mms, MmsConfig};
use super::refine::{Refine, RefineConfig, refine};
use super::resample::resize_flow;
use super::weights;
use crate::error::{Error, Result};
use crate::imaging::resize::downscale;
use crate::types::{Flow, Image};

/// The shipped weights, compiled into the binary and named by `--weights NAME` (see docs/training.md
/// for the commands that made them): `mms-small-real` (the training campaign's weights, cooled
/// down, after stages 1–7 and nine campaigns of photographic, large-motion, road, flat-object
/// and large-frame training; its stage in its model card; the best flow on real images, so
/// `default` for the flow commands and the tracker) and `mms-small` (stage 3, on the
/// generator's chairs; `pins live`'s default).
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

/// The weights the tracker uses by default (`pins track --frames`, track experiments, `pins
/// live --config`): the flow commands' own, run with the frame made 1280 px wide
/// (`track::config::TRACK_WIDTH`: twice a 640×480 frame).
pub const TRACK_WEIGHTS: &str = DEFAULT_WEIGHTS;

/// The weights of `pins live` without `--config`: stage 3, the fastest to see a small mover at
/// the frame's own size (`cli::live`).
pub const LIVE_WEIGHTS: &str = "mms-small";

/// Parses `--start`: `coarse` (from the network's own flow at half resolution) or `zero`.
pub fn parse_start(s: &str) -> Result<bool> {
    match s {
        "coarse" => Ok(true),
        "zero" => Ok(false),
        _ => Err(Error::invalid(
            "--start",
            format!("expected coarse or zero, got {s:?}"),
        )),
    }
}

/// Whether `name` is `default` or a built-in weights name rather than a file.
pub fn is_builtin(name: &str) -> bool {
    name == "default" || BUILTIN_WEIGHTS.iter().any(|(n, _, _)| *n == name)
}

/// A loaded network ready to run, with how it starts and the refinement its flow gets: by
/// default the flow commands' settings, the coarse start and the variational refinement (see
/// [`super::refine`]).
pub struct Predictor {
    pub model: Mms,
    pub config: MmsConfig,
    pub device: Device,
    pub refine: Option<RefineConfig>,
    /// Start from the flow the network finds at half resolution (where every motion is half as
    /// long), upsampled, instead of from zero: large motions are found, then refined.
    pub coarse_start: bool,
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
            coarse_start: true,
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

    /// The same predictor, starting from its half-resolution flow when `on`.
    pub fn with_coarse_start(mut self, on: bool) -> Self {
        self.coarse_start = on;
        self
    }

    /// The network's own flow, without the refinement: from zero, or from its flow at half
    /// resolution (each side halved, at least the network's smallest input) when
    /// `coarse_start` is set.
    pub fn predict_network(&self, img1: &Image, img2: &Image, iters: usize) -> Result<Flow> {
        let (h, w) = (img1.height(), img1.width());
        let init = if self.coarse_start && h.min(w) >= 2 * self.config.min_side().max(16) {
            let (a, b) = (downscale(img1, 0.5)?, downscale(img2, 0.5)?);
            let coarse = predict_flow(&self.model, &self.config, &a, &b, iters, &self.device)?;
            Some(resize_flow(&coarse, h, w)?)
        } else {
            None
        };
        predict_flow_from(
            &self.model,
            &self.config,
            img1,
            img2,
            iters,
            &self.device,
            init.as_ref(),
        )
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
    predict_flow_from(model, config, img1, img2, iters, device, None)
}

/// [`predict_flow`] starting from the flow `init` (the pair's size) instead of zero.
pub fn predict_flow_from(
    model: &Mms,
    config: &MmsConfig,
    img1: &Image,
    img2: &Image,
    iters: usize,
    device: &Device,
    init: Option<&Flow>,
) -> Result<Flow> {
    let start = match init {
        Some(f) => Start::Flow(f),
        None => Start::Zero,
    };
    let run = Network {
        model,
        config,
        device,
    };
    Ok(run.pair(img1, img2, iters, start, None, None)?.flow)
}

/// Where a network run starts.
pub enum Start<'a> {
    Zero,
    /// A flow at the pair's size, in pixels.
    Flow(&'a Flow),
    /// A flow on the network's grid of the padded pair (`[1, 2, H'/8, W'/8]`, 1/8-resolution
    /// pixels).
    Grid(Box<Tensor<4>>),
}

/// The last frame a network run saw, kept by a caller that runs the frames of a video in
/// order: its feature encoding (the first frame's of the next pair) and the grid flow that
/// ended at it (the next pair's warm start).
pub struct LastFrame {
    pub image: Image,
    /// `[1, C, H'/8, W'/8]`
    pub features: Tensor<4>,
    /// `[1, 2, H'/8, W'/8]`, 1/8-resolution pixels.
    pub flow8: Tensor<4>,
}

impl LastFrame {
    /// Whether this is `image` (same size, same pixels): then what it holds belongs to it.
    pub fn is(&self, image: &Image) -> bool {
        self.image.shape() == image.shape() && self.image.data() == image.data()
    }
}

/// One pair's network output.
pub struct NetworkPair {
    pub flow: Flow,
    /// The updates run.
    pub iters: usize,
    /// Whether the first frame's features came from the caller's [`LastFrame`].
    pub reused: bool,
    /// The second frame, its features and the grid flow: the next pair's [`LastFrame`].
    pub last: LastFrame,
}

/// A network and the device it runs on.
pub struct Network<'a> {
    pub model: &'a Mms,
    pub config: &'a MmsConfig,
    pub device: &'a Device,
}

impl Network<'_> {
    /// Runs the network on one pair. Images must have the same size; grey images are repeated
    /// to RGB. When `last` is the first image, its features are reused (the same arithmetic
    /// as encoding it again: each image is encoded on its own); `stop` ends the updates early
    /// (see [`Mms::iterate`]).
    pub fn pair(
        &self,
        img1: &Image,
        img2: &Image,
        iters: usize,
        start: Start<'_>,
        last: Option<LastFrame>,
        stop: Option<f32>,
    ) -> Result<NetworkPair> {
        check_pair(img1, img2, iters)?;
        let device = self.device;
        let (h, w) = (img1.height(), img1.width());
        let padder = InputPadder::new(h, w, self.config.min_side());
        let a = padder.pad(image_tensor(img1, device));
        let b = padder.pad(image_tensor(img2, device));
        let init = match start {
            Start::Zero => None,
            Start::Flow(f) if (f.height(), f.width()) == (h, w) => {
                Some(init_tensor(f, &padder, device)?)
            }
            Start::Flow(f) => {
                return Err(Error::shape(
                    "initial flow",
                    format!("{w}x{h}"),
                    format!("{}x{}", f.width(), f.height()),
                ));
            }
            Start::Grid(t) => Some(*t),
        };
        let model = self.model;
        let cached = last.filter(|l| l.is(img1)).map(|l| l.features);
        let reused = cached.is_some();
        let (f1, f2, context) = match cached {
            // Only the new frame's features, beside the first frame's context.
            Some(f1) => {
                let (f2, context) = crate::flow::ops::both(
                    &a,
                    || model.features(b.clone()),
                    || model.context(a.clone()),
                );
                (f1, f2, context)
            }
            // Both frames in one batch, as `Mms::forward_from` does.
            None => {
                let (features, context) = crate::flow::ops::both(
                    &a,
                    || model.features(Tensor::cat(vec![a.clone(), b.clone()], 0)),
                    || model.context(a.clone()),
                );
                (
                    features.clone().narrow(0, 0, 1),
                    features.narrow(0, 1, 1),
                    context,
                )
            }
        };
        let out = model.iterate(f1, f2.clone(), context, iters, false, init, stop);
        let pred = out
            .predictions
            .into_iter()
            .last()
            .ok_or_else(|| Error::invalid("model", "no prediction"))?;
        let flow = padder.unpad(pred); // [1, 2, H, W]
        let data: Vec<f32> = flow
            .into_data()
            .try_to_vec::<f32>()
            .map_err(|e| Error::invalid("model output", format!("{e:?}")))?;
        let flow = Flow::from_vec(h, w, data)?;
        if flow.data().iter().any(|v| !v.is_finite()) {
            return Err(Error::invalid(
                "model output",
                "the network produced non-finite flow",
            ));
        }
        Ok(NetworkPair {
            flow,
            iters: out.iters,
            reused,
            last: LastFrame {
                image: img2.clone(),
                features: f2,
                flow8: out.flow8,
            },
        })
    }
}

/// Checks a pair before the network sees it: the same size, finite pixels, 1..=256 updates.
fn check_pair(img1: &Image, img2: &Image, iters: usize) -> Result<()> {
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
    img2.check_finite("second image")
}

/// `flow` (`[2, H, W]`, pixels) padded as the images are and averaged over the 8×8 cells of
/// the network's grid, in 1/8-resolution pixels.
///
/// # Shapes
/// → `[1, 2, H'/8, W'/8]`
fn init_tensor(flow: &Flow, padder: &InputPadder, device: &Device) -> Result<Tensor<4>> {
    if flow.data().iter().any(|v| !v.is_finite()) {
        return Err(Error::invalid("initial flow", "holds non-finite vectors"));
    }
    let (h, w) = (flow.height(), flow.width());
    let t = Tensor::<4>::from_data(TensorData::new(flow.data().to_vec(), [1, 2, h, w]), device);
    let padded: Vec<f32> = padder
        .pad(t)
        .into_data()
        .try_to_vec::<f32>()
        .map_err(|e| Error::invalid("initial flow", format!("{e:?}")))?;
    let (ph, pw) = padder.padded_size();
    let (ch, cw) = (ph / 8, pw / 8);
    let mut cells = vec![0.0f32; 2 * ch * cw];
    for c in 0..2 {
        for y in 0..ph {
            for x in 0..pw {
                cells[(c * ch + y / 8) * cw + x / 8] += padded[(c * ph + y) * pw + x] / 512.0;
            }
        }
    }
    Ok(Tensor::<4>::from_data(
        TensorData::new(cells, [1, 2, ch, cw]),
        device,
    ))
}
