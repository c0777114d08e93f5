//! Training and evaluation data: the pairs of a dataset folder written by `pins generate` (or
//! any FlyingChairs-named folder), a held-out split, and batches with random crops and
//! flow-consistent augmentation.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use burn::prelude::*;
use rand::RngExt;
use serde::{Deserialize, Serialize};

use crate::dataset::shards::{ShardSet, is_shard_folder};
use crate::error::{Error, Result};
use crate::io;
use crate::rng;
use crate::scene::readers::{Layout, PairPaths, discover};
use crate::types::{Flow, Image};

/// A dataset of image pairs with ground-truth flow.
#[derive(Clone, Debug)]
pub struct FlowDataset {
    pub root: PathBuf,
    pub pairs: Vec<PairPaths>,
    /// A shard folder (`pins pack`): the set, and each pair's sample index in it (parallel to
    /// `pairs`). The pairs are then read out of the tar files, never unpacked.
    shards: Option<(Arc<ShardSet>, Vec<usize>)>,
}

impl FlowDataset {
    /// Opens `root` (a `pins generate` folder or any FlyingChairs, Sintel, Middlebury or KITTI
    /// layout) and keeps the pairs that have flow. Errors when none has.
    pub fn open(root: &Path) -> Result<Self> {
        let (pairs, shards): (Vec<PairPaths>, _) = if is_shard_folder(root) {
            let set = Arc::new(ShardSet::open(root)?);
            let (ids, pairs) = set
                .pairs()
                .into_iter()
                .enumerate()
                .filter(|(_, p)| p.flow.is_some())
                .unzip();
            (pairs, Some((set, ids)))
        } else {
            let pairs = discover(root, Layout::Auto)?
                .into_iter()
                .filter(|p| p.flow.is_some())
                .collect();
            (pairs, None)
        };
        if pairs.is_empty() {
            return Err(Error::invalid(
                "dataset",
                format!("{}: no image pair has ground-truth flow", root.display()),
            ));
        }
        Ok(Self {
            root: root.to_path_buf(),
            pairs,
            shards,
        })
    }

    /// The part `range` of the dataset (same root and source).
    fn slice(&self, range: std::ops::Range<usize>) -> FlowDataset {
        FlowDataset {
            root: self.root.clone(),
            pairs: self.pairs[range.clone()].to_vec(),
            shards: self
                .shards
                .as_ref()
                .map(|(set, ids)| (set.clone(), ids[range].to_vec())),
        }
    }

    /// Splits off the last `fraction` of the pairs (at least one, and at least one left for
    /// training when there are two or more) as a held-out validation set.
    pub fn split(&self, fraction: f64) -> (FlowDataset, FlowDataset) {
        let n = self.pairs.len();
        let val = ((n as f64 * fraction).round() as usize).clamp(1, n.saturating_sub(1).max(1));
        let cut = n - val.min(n);
        let train = if cut == 0 {
            self.clone()
        } else {
            self.slice(0..cut)
        };
        (train, self.slice(cut..n))
    }

    /// Fails unless some pair has at least one known ground-truth vector. Reads the flows in
    /// order and stops at the first known vector, so a normal dataset costs one flow file.
    pub fn check_has_known_flow(&self) -> Result<()> {
        for i in 0..self.pairs.len() {
            if self.pairs[i].flow.is_some() {
                let flow = self.read_flow(i)?;
                if flow.valid_mask().iter().any(|&v| v) {
                    return Ok(());
                }
            }
        }
        Err(Error::invalid(
            "dataset",
            format!(
                "{}: none of its {} flow files holds a known vector (every pixel is unknown \
                 or invalid), so there is nothing to train or score against",
                self.root.display(),
                self.pairs.len()
            ),
        ))
    }

    /// What identifies the dataset's content without reading it: the pairs' names and the
    /// names (relative to the root) and byte sizes of their files, hashed (SHA-256). Moving the
    /// folder keeps it; adding, removing, renaming or resizing a file changes it.
    pub fn fingerprint(&self) -> Result<DataFingerprint> {
        use sha2::{Digest, Sha256};
        let mut hash = Sha256::new();
        for (i, p) in self.pairs.iter().enumerate() {
            hash.update(p.name.as_bytes());
            hash.update([0]);
            for (role, f) in [
                ("img1", Some(&p.img1)),
                ("img2", Some(&p.img2)),
                ("flow", p.flow.as_ref()),
            ]
            .into_iter()
            .filter_map(|(role, f)| Some((role, f?)))
            {
                let rel = f.strip_prefix(&self.root).unwrap_or(f);
                let len = match &self.shards {
                    Some((set, ids)) => set.member_size(ids[i], role)?.unwrap_or(0),
                    None => std::fs::metadata(f).map_err(|e| Error::io(f, e))?.len(),
                };
                hash.update(rel.to_string_lossy().as_bytes());
                hash.update([0]);
                hash.update(len.to_le_bytes());
            }
        }
        let digest = hash.finalize();
        Ok(DataFingerprint {
            pairs: self.pairs.len(),
            sha256: digest.iter().map(|b| format!("{b:02x}")).collect(),
        })
    }

    /// Loads pair `i`: two 3-channel images of equal size and the flow (NaN where unknown).
    pub fn load(&self, i: usize) -> Result<(Image, Image, Flow)> {
        let p = &self.pairs[i];
        let (a, b) = match &self.shards {
            Some((set, ids)) => {
                let read = |role: &str, path: &Path| -> Result<Image> {
                    let bytes = set.read(ids[i], role)?.unwrap_or_default();
                    io::decode_image(&bytes, path)
                };
                let (a, b) = (read("img1", &p.img1)?, read("img2", &p.img2)?);
                if a.shape() != b.shape() {
                    return Err(Error::shape(
                        format!("image pair {}", p.name),
                        format!("{}x{}", a.width(), a.height()),
                        format!("{}x{}", b.width(), b.height()),
                    ));
                }
                (a, b)
            }
            None => io::read_image_pair(&p.img1, &p.img2)?,
        };
        let flow_path = p
            .flow
            .as_ref()
            .ok_or_else(|| Error::invalid("pair", format!("{} has no flow", p.name)))?;
        let flow = self.read_flow(i)?;
        if (flow.height(), flow.width()) != (a.height(), a.width()) {
            return Err(Error::shape(
                format!("flow {}", flow_path.display()),
                format!("{}x{}", a.width(), a.height()),
                format!("{}x{}", flow.width(), flow.height()),
            ));
        }
        Ok((to_rgb(a), to_rgb(b), flow))
    }
}

impl FlowDataset {
    /// The flow of pair `i`, from its file or its shard.
    fn read_flow(&self, i: usize) -> Result<Flow> {
        let p = &self.pairs[i];
        let path = p
            .flow
            .as_ref()
            .ok_or_else(|| Error::invalid("pair", format!("{} has no flow", p.name)))?;
        match &self.shards {
            Some((set, ids)) => {
                let bytes = set.read(ids[i], "flow")?.unwrap_or_default();
                io::decode_flow(&bytes, path)
            }
            None => io::read_flow(path),
        }
    }
}

/// The identity of a dataset's content, stored in training checkpoints (see
/// [`FlowDataset::fingerprint`]).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct DataFingerprint {
    /// Pairs the data holds; 0 for pairs made on the fly (`super::train::stream`).
    pub pairs: usize,
    pub sha256: String,
}

impl DataFingerprint {
    /// "N pairs (fingerprint abcdef012345)", or "pairs made on the fly (fingerprint …)".
    pub fn describe(&self) -> String {
        let short = self.sha256.get(..12).unwrap_or(&self.sha256);
        if self.pairs == 0 {
            format!("pairs made on the fly (fingerprint {short})")
        } else {
            format!("{} pairs (fingerprint {short})", self.pairs)
        }
    }
}

/// Repeats a grey channel three times; keeps 3 channels; drops alpha.
pub fn to_rgb(img: Image) -> Image {
    let (c, h, w) = img.shape();
    match c {
        3 => img,
        1 => Image::from_vec(3, h, w, [img.plane(0), img.plane(0), img.plane(0)].concat())
            .unwrap_or(img),
        _ => Image::from_vec(3, h, w, [img.plane(0), img.plane(1), img.plane(2)].concat())
            .unwrap_or(img),
    }
}

/// Augmentation settings (RAFT-style, without spatial rescaling).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AugmentConfig {
    pub flip_horizontal: f64,
    pub flip_vertical: f64,
    /// Brightness factor range, applied to both frames.
    pub brightness: [f32; 2],
    /// Contrast factor range about the mean, both frames.
    pub contrast: [f32; 2],
    /// Gamma range, both frames.
    pub gamma: [f32; 2],
    /// Probability that frame 2 gets its own extra brightness change (±10 %).
    pub asymmetric: f64,
}

impl Default for AugmentConfig {
    fn default() -> Self {
        Self {
            flip_horizontal: 0.5,
            flip_vertical: 0.1,
            brightness: [0.7, 1.3],
            contrast: [0.7, 1.3],
            gamma: [0.8, 1.25],
            asymmetric: 0.2,
        }
    }
}

/// One training example after cropping and augmentation, planar.
pub struct Example {
    /// The crop's `(height, width)`.
    pub size: (usize, usize),
    pub img1: Vec<f32>,
    pub img2: Vec<f32>,
    pub flow: Vec<f32>,
    pub valid: Vec<f32>,
}

/// Crops `(h, w)` at a random place and augments; flips keep the flow consistent (a horizontal
/// flip negates u, a vertical one negates v). Images smaller than the crop are an error.
pub fn make_example(
    a: &Image,
    b: &Image,
    flow: &Flow,
    crop: (usize, usize),
    aug: &AugmentConfig,
    r: &mut rng::Rng,
) -> Result<Example> {
    let (_, h, w) = a.shape();
    let (ch, cw) = crop;
    if h < ch || w < cw {
        return Err(Error::invalid(
            "crop",
            format!("{cw}x{ch} is larger than a {w}x{h} training image"),
        ));
    }
    let (y0, x0) = (r.random_range(0..=h - ch), r.random_range(0..=w - cw));
    let flip_h = r.random_bool(aug.flip_horizontal.clamp(0.0, 1.0));
    let flip_v = r.random_bool(aug.flip_vertical.clamp(0.0, 1.0));
    let range = |r: &mut rng::Rng, v: [f32; 2]| {
        if v[0] < v[1] {
            r.random_range(v[0]..=v[1])
        } else {
            v[0]
        }
    };
    let bright = range(r, aug.brightness);
    let contrast = range(r, aug.contrast);
    let gamma = range(r, aug.gamma);
    let extra = if r.random_bool(aug.asymmetric.clamp(0.0, 1.0)) {
        r.random_range(0.9f32..=1.1)
    } else {
        1.0
    };
    let src = |y: usize, x: usize| -> (usize, usize) {
        (
            y0 + if flip_v { ch - 1 - y } else { y },
            x0 + if flip_h { cw - 1 - x } else { x },
        )
    };
    let n = ch * cw;
    let mut out = Example {
        size: (ch, cw),
        img1: vec![0.0; 3 * n],
        img2: vec![0.0; 3 * n],
        flow: vec![0.0; 2 * n],
        valid: vec![0.0; n],
    };
    for (img, dst, k) in [(a, &mut out.img1, 1.0f32), (b, &mut out.img2, extra)] {
        for c in 0..3 {
            let plane = img.plane(c);
            let mean =
                plane.iter().map(|&v| v as f64).sum::<f64>() as f32 / plane.len().max(1) as f32;
            for y in 0..ch {
                for x in 0..cw {
                    let (sy, sx) = src(y, x);
                    let v = plane[sy * w + sx];
                    let v = ((v - mean) * contrast + mean) * bright * k;
                    dst[c * n + y * cw + x] = v.clamp(0.0, 1.0).powf(gamma);
                }
            }
        }
    }
    for y in 0..ch {
        for x in 0..cw {
            let (sy, sx) = src(y, x);
            let (u, v) = flow.get(sy, sx);
            let i = y * cw + x;
            if u.is_finite() && v.is_finite() {
                out.flow[i] = if flip_h { -u } else { u };
                out.flow[n + i] = if flip_v { -v } else { v };
                out.valid[i] = 1.0;
            }
        }
    }
    Ok(out)
}

/// A batch as tensors: images `[B, 3, H, W]`, flow `[B, 2, H, W]`, valid `[B, 1, H, W]`.
pub struct Batch {
    pub img1: Tensor<4>,
    pub img2: Tensor<4>,
    pub flow: Tensor<4>,
    pub valid: Tensor<4>,
}

impl Batch {
    /// Stacks examples of one size onto `device`; examples of different sizes are an error.
    pub fn stack(examples: Vec<Example>, device: &Device) -> Result<Self> {
        let b = examples.len();
        let (h, w) = examples.first().map_or((0, 0), |e| e.size);
        if let Some(e) = examples.iter().find(|e| e.size != (h, w)) {
            return Err(Error::invalid(
                "batch",
                format!(
                    "examples of {}x{} and {}x{} cannot share a batch",
                    w, h, e.size.1, e.size.0
                ),
            ));
        }
        let (mut i1, mut i2, mut f, mut v) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for e in examples {
            i1.extend(e.img1);
            i2.extend(e.img2);
            f.extend(e.flow);
            v.extend(e.valid);
        }
        let t = |data: Vec<f32>, c: usize| {
            Tensor::<4>::from_data(TensorData::new(data, [b, c, h, w]), device)
        };
        Ok(Batch {
            img1: t(i1, 3),
            img2: t(i2, 3),
            flow: t(f, 2),
            valid: t(v, 1),
        })
    }
}

/// An image as a `[1, 3, H, W]` tensor.
pub fn image_tensor(img: &Image, device: &Device) -> Tensor<4> {
    let img = to_rgb(img.clone());
    let (_, h, w) = img.shape();
    Tensor::<4>::from_data(TensorData::new(img.into_vec(), [1, 3, h, w]), device)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flips_keep_flow_consistent() {
        let (h, w) = (8, 10);
        let mut a = Image::zeros(3, h, w);
        a.set(0, 2, 3, 1.0);
        let mut flow = Flow::zeros(h, w);
        flow.set(2, 3, 2.0, -1.0);
        flow.set(0, 0, f32::NAN, 0.0);
        let aug = AugmentConfig {
            flip_horizontal: 1.0,
            flip_vertical: 1.0,
            brightness: [1.0, 1.0],
            contrast: [1.0, 1.0],
            gamma: [1.0, 1.0],
            asymmetric: 0.0,
        };
        let mut r = rng::stream(1, &[0]);
        let e = make_example(&a, &a, &flow, (h, w), &aug, &mut r).unwrap();
        let (y, x) = (h - 1 - 2, w - 1 - 3);
        assert_eq!(e.img1[y * w + x], 1.0);
        assert_eq!((e.flow[y * w + x], e.flow[h * w + y * w + x]), (-2.0, 1.0));
        assert_eq!(
            e.valid[(h - 1) * w + (w - 1)],
            0.0,
            "unknown flow is invalid"
        );
        assert!(make_example(&a, &a, &flow, (16, 16), &aug, &mut r).is_err());
    }
}
