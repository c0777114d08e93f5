//! Training pairs made on the fly (Note S11's training data, unbounded): a mix of generator
//! configs (chairs scenes through the metalens camera), each drawn with its weight, every pair
//! made in memory when a step needs it and never seen twice. Slot `b` of step `s` draws a source
//! by weight and is that generator's sample `count + s·batch + b` — the bytes `pins generate`
//! would write for it; the indices start past the config's `count`, so a stream never remakes
//! the pairs a folder of the same config holds. The data of a step is a function of (seed,
//! step) alone and `--resume` replays it exactly; no disk is used.
//!
//! The stream file (`--data mix.json`):
//!
//! ```json
//! {"sources": [{"generator": "data/1_real.json", "weight": 800},
//!              {"generator": "data/7_small.json", "weight": 800}]}
//! ```
//!
//! Paths are relative to the stream file. A source may name its own `"crop": [h, w]` (its
//! frames must hold it; the run's crop otherwise): a step's batch is cut to the crop of its
//! first pair's source, and its other slots draw among the sources of that crop, so that a
//! stream can mix, say, a tenth of frame-sized crops of large scenes into a run of small ones
//! (the network's feature normalisation takes a whole frame's statistics, and a frame several
//! times its training crops is otherwise out of what it saw).
//!
//! A source may also name an `"upscale"` factor in [1, 4]: its pairs, made at the generator's
//! size (the camera's blur and noise at its pixels), are made larger by that factor as `pins
//! infer --scale` makes frames larger before the network (`flow::scale`: bilinear, the flow's
//! vectors multiplied with the size). The tracker runs MMS at 2 to 4 times a camera's frame
//! (`flow.scale`), where a frame is smooth, its noise in blobs of several pixels and a small
//! mover a few dozen pixels across; such a source is that input with exact flow.
//!
//! The validation pairs are a fixed set, apart from every training pair: pair `j` comes from
//! the source whose share of the weights holds `(j + ½) / n` (each source in proportion), at
//! sample index `VAL_BASE + j`.
//!
//! The fingerprint (kept by checkpoints, so that a resume on other data is refused) hashes each
//! source's share of the weights, its config as written (as a JSON value, keys sorted: not its
//! layout), its photographs' names and pixels, and the bytes of one probe sample (`PROBE`) made
//! when the stream opens: what the configs do not say — the defaults, the PSF file, the
//! generator's code, the machine's arithmetic — shows in the probe. A knob added to the
//! generator later, off by default, changes neither, so a campaign goes on across it.

use std::path::{Path, PathBuf};

use rand::RngExt;
use serde::{Deserialize, Serialize};

use crate::dataset::{Generator, GeneratorConfig, SceneSpec};
use crate::error::Result;
use crate::flow::data::DataFingerprint;
use crate::flow::resample::resize_flow;
use crate::flow::scale::MAX_SCALE;
use crate::imaging::resize::{resize_to, scaled_size};
use crate::rng;
use crate::types::{Flow, Image};

/// The first sample index of the validation pairs; training pairs use `count + step · batch +
/// slot`, far below it.
pub const VAL_BASE: usize = 1 << 40;

/// The sample index of each source's probe, hashed into the fingerprint (no training or
/// validation pair uses it).
pub const PROBE: usize = VAL_BASE - 1;

/// One source of a stream file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StreamSource {
    /// A generator config (JSON); relative to the stream file.
    pub generator: PathBuf,
    /// The source's share of the pairs, relative to the other sources' weights.
    pub weight: f64,
    /// The crop `[h, w]` its pairs are cut to, when not the run's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub crop: Option<[usize; 2]>,
    /// Its pairs made larger by this factor in [1, `flow::scale::MAX_SCALE`] after the camera
    /// (bilinear, the flow's vectors scaled with the size), as MMS sees frames run at a scale.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub upscale: Option<f64>,
}

/// A stream file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StreamConfig {
    pub sources: Vec<StreamSource>,
}

/// A stream ready to make pairs: each source's generator and the cumulative shares.
pub struct Stream {
    path: PathBuf,
    generators: Vec<Generator>,
    /// Each source's first training index: its config's `count`.
    first: Vec<usize>,
    /// Cumulative shares of the weights, ending at 1.
    cumulative: Vec<f64>,
    fingerprint: DataFingerprint,
    /// Each source's frame, `(height, width)`.
    frames: Vec<(usize, usize)>,
    /// Each source's own crop, if it has one.
    crops: Vec<Option<[usize; 2]>>,
    /// Each source's upscale factor, if it has one.
    upscales: Vec<Option<f64>>,
}

/// Whether `path` names a stream file rather than a folder of pairs.
pub fn is_stream_file(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"))
}

impl Stream {
    /// Reads the stream file and every generator config it names (their photographs too),
    /// refusing what cannot make training pairs.
    pub fn open(path: &Path) -> Result<Self> {
        let config: StreamConfig = crate::io::read_json(path)?;
        if config.sources.is_empty() {
            return Err(crate::io::in_config(path, "sources: none given"));
        }
        let base = path.parent().unwrap_or(Path::new(""));
        let total: f64 = config.sources.iter().map(|s| s.weight).sum();
        if !total.is_finite() {
            return Err(crate::io::in_config(
                path,
                format!("sources: the weights add up to {total}"),
            ));
        }
        let mut generators = Vec::new();
        let mut first = Vec::new();
        let mut cumulative = Vec::new();
        let mut acc = 0.0;
        let mut frames = Vec::new();
        let mut crops = Vec::new();
        let mut upscales = Vec::new();
        use sha2::{Digest, Sha256};
        let mut hash = Sha256::new();
        for (k, source) in config.sources.iter().enumerate() {
            if !(source.weight.is_finite() && source.weight > 0.0) {
                return Err(crate::io::in_config(
                    path,
                    format!(
                        "sources[{k}].weight: must be a positive number, got {}",
                        source.weight
                    ),
                ));
            }
            let file = base.join(&source.generator);
            let generator_config = GeneratorConfig::from_file(&file)?;
            let (height, width, photos) = match &generator_config.scene {
                SceneSpec::Chairs(c) => (c.height, c.width, c.photos.as_ref()),
                SceneSpec::Movers(m) => (m.height, m.width, None),
                _ => {
                    return Err(crate::io::in_config(
                        &file,
                        "scene.kind: a stream makes pairs of chairs or movers scenes (the other \
                         kinds are fixed patterns or a finite dataset: generate them into a \
                         folder)",
                    ));
                }
            };
            if let Some(c) = source.crop
                && !super::config::crop_fits_the_network(c)
            {
                return Err(crate::io::in_config(
                    path,
                    format!(
                        "sources[{k}].crop: {c:?}; each side must be a multiple of 8, at least 64"
                    ),
                ));
            }
            if let Some(u) = source.upscale
                && !(u.is_finite() && (1.0..=MAX_SCALE).contains(&u))
            {
                return Err(crate::io::in_config(
                    path,
                    format!("sources[{k}].upscale: must be in [1, {MAX_SCALE}], got {u}"),
                ));
            }
            frames.push(match source.upscale {
                Some(u) => scaled_size(height, width, u),
                None => (height, width),
            });
            crops.push(source.crop);
            upscales.push(source.upscale);
            // The data's identity: the share, the config as written (its keys in order, so
            // neither its layout nor a move of the checkout counts; a knob added to the code
            // later, off by default, leaves it as it was), the photographs, a probe.
            let written: serde_json::Value = crate::io::read_json(&file)?;
            hash.update((source.weight / total).to_le_bytes());
            hash.update(
                serde_json::to_string(&written)
                    .unwrap_or_default()
                    .as_bytes(),
            );
            hash.update([0]);
            // A source's own crop is part of what the run trains on (absent, nothing is hashed:
            // streams written before crops could be named keep their identity).
            if let Some(c) = source.crop {
                hash.update(b"crop");
                hash.update((c[0] as u64).to_le_bytes());
                hash.update((c[1] as u64).to_le_bytes());
            }
            // So is its upscale factor (absent, nothing is hashed, as for the crop).
            if let Some(u) = source.upscale {
                hash.update(b"upscale");
                hash.update(u.to_le_bytes());
            }
            if let Some(photos) = photos {
                for p in photos.library()?.iter() {
                    hash.update(p.name.as_bytes());
                    hash.update([0]);
                    hash_floats(&mut hash, p.image.data());
                }
            }
            first.push(generator_config.count);
            let generator = Generator::new(generator_config)?;
            let (a, b, flow) = generator.pair(PROBE)?;
            for plane in [a.data(), b.data()] {
                hash_floats(&mut hash, plane);
            }
            if let Some(f) = flow {
                hash_floats(&mut hash, f.data());
            }
            generators.push(generator);
            acc += source.weight / total;
            cumulative.push(acc);
        }
        if let Some(last) = cumulative.last_mut() {
            *last = 1.0;
        }
        let digest = hash.finalize();
        Ok(Self {
            path: path.to_path_buf(),
            generators,
            first,
            cumulative,
            fingerprint: DataFingerprint {
                pairs: 0,
                sha256: digest.iter().map(|b| format!("{b:02x}")).collect(),
            },
            frames,
            crops,
            upscales,
        })
    }

    /// The stream file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The data's identity: a hash of each source's weight, config and photographs; `pairs`
    /// is 0 (a stream has no end).
    pub fn fingerprint(&self) -> &DataFingerprint {
        &self.fingerprint
    }

    /// The smallest frame any source makes, `(height, width)`.
    #[cfg(test)]
    fn smallest_frame(&self) -> (usize, usize) {
        self.frames.iter().fold((usize::MAX, usize::MAX), |m, f| {
            (m.0.min(f.0), m.1.min(f.1))
        })
    }

    /// Each source's frame `(height, width)` and the crop its pairs are cut to (`default`, the
    /// run's, unless it has its own).
    pub fn frames_and_crops(&self, default: [usize; 2]) -> Vec<((usize, usize), [usize; 2])> {
        self.frames
            .iter()
            .zip(&self.crops)
            .map(|(&f, c)| (f, c.unwrap_or(default)))
            .collect()
    }

    /// The source whose share of the weights holds `t` in [0, 1).
    fn source_at(&self, t: f64) -> usize {
        self.cumulative
            .iter()
            .position(|&c| t < c)
            .unwrap_or(self.cumulative.len() - 1)
    }

    /// Training pair `slot` of step `step` (of `batch` pairs): its source drawn with `r` by
    /// weight, its sample index `count + step · batch + slot`.
    pub fn train_pair(
        &self,
        step: usize,
        slot: usize,
        batch: usize,
        default: [usize; 2],
        within: Option<[usize; 2]>,
        r: &mut rng::Rng,
    ) -> Result<(Image, Image, Flow, [usize; 2])> {
        let t = r.random_range(0.0..1.0);
        let crop_of = |k: usize| self.crops[k].unwrap_or(default);
        let k = match within {
            Some(c) if (0..self.crops.len()).any(|k| crop_of(k) != c) => {
                self.source_of_crop(t, c, default)
            }
            _ => self.source_at(t),
        };
        let (a, b, f) = self.make(k, self.first[k] + step * batch + slot)?;
        Ok((a, b, f, crop_of(k)))
    }

    /// The source whose share among the sources of crop `crop` holds `t` in [0, 1).
    fn source_of_crop(&self, t: f64, crop: [usize; 2], default: [usize; 2]) -> usize {
        let shares: Vec<(usize, f64)> = (0..self.crops.len())
            .filter(|&k| self.crops[k].unwrap_or(default) == crop)
            .map(|k| {
                (
                    k,
                    self.cumulative[k] - k.checked_sub(1).map_or(0.0, |j| self.cumulative[j]),
                )
            })
            .collect();
        let total: f64 = shares.iter().map(|s| s.1).sum();
        let mut acc = 0.0;
        for &(k, share) in &shares {
            acc += share / total;
            if t < acc {
                return k;
            }
        }
        shares.last().map_or(0, |s| s.0)
    }

    /// Validation pair `j` of `n`: from the source whose share holds `(j + ½) / n`, at sample
    /// index `VAL_BASE + j`.
    pub fn val_pair(&self, j: usize, n: usize) -> Result<(Image, Image, Flow)> {
        let k = self.source_at((j as f64 + 0.5) / n.max(1) as f64);
        self.make(k, VAL_BASE + j)
    }

    /// Sample `index` of source `k`, in colour, made larger by the source's upscale factor; a
    /// still scene's flow is zero everywhere.
    fn make(&self, k: usize, index: usize) -> Result<(Image, Image, Flow)> {
        let (mut a, mut b, flow) = self.generators[k].pair(index)?;
        let mut flow = flow.unwrap_or_else(|| Flow::zeros(a.height(), a.width()));
        if let Some(u) = self.upscales[k] {
            // [c, h, w] → [c, h·u, w·u] as `flow::scale::predict_scaled` resizes its frames;
            // the flow [2, h·u, w·u] in the larger frame's pixels.
            let (h, w) = scaled_size(a.height(), a.width(), u);
            (a, b) = (resize_to(&a, h, w)?, resize_to(&b, h, w)?);
            flow = resize_flow(&flow, h, w)?;
        }
        Ok((
            crate::flow::data::to_rgb(a),
            crate::flow::data::to_rgb(b),
            flow,
        ))
    }
}

/// Adds the bytes of `values` (little-endian) to `hash`.
fn hash_floats(hash: &mut sha2::Sha256, values: &[f32]) {
    use sha2::Digest;
    let mut bytes = Vec::with_capacity(4 * values.len());
    for v in values {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    hash.update(&bytes);
}

#[cfg(test)]
mod tests;
