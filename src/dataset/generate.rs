//! The generator: scene → camera → `NNNNN_img1.png`, `NNNNN_img2.png`, `NNNNN_flow.flo`
//! (FlyingChairs naming) and a metadata sidecar per sample, in parallel, resumable, with
//! every byte a function of (config, seed, sample index) alone.

use std::path::Path;

use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::config::{GeneratorConfig, SceneSpec};
use super::folder;
use super::integrity::{Depth, SampleProblem, check_sample, record_file};
use super::manifest::{FlowStats, Manifest, SampleMeta};
use crate::error::{Error, Result};
use crate::imaging::{Camera, psf_source};
use crate::io::{self, BitDepth};
use crate::rng;
use crate::scene::patterns;
use crate::scene::readers::{PairPaths, discover};
use crate::types::{Flow, Image};

/// Shard `index` of `count`: a contiguous block of sample indices.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl Shard {
    pub const ALL: Shard = Shard { index: 0, count: 1 };

    /// Parses `K/N` with `0 <= K < N`.
    pub fn parse(s: &str) -> Result<Self> {
        let bad = || {
            Error::invalid(
                "--shard",
                format!("expected K/N with 0 <= K < N, got {s:?}"),
            )
        };
        let (k, n) = s.split_once('/').ok_or_else(bad)?;
        let (k, n) = (
            k.trim().parse::<usize>().map_err(|_| bad())?,
            n.trim().parse::<usize>().map_err(|_| bad())?,
        );
        if n == 0 || k >= n {
            return Err(bad());
        }
        Ok(Shard { index: k, count: n })
    }

    /// The sample indices of this shard out of `total`.
    pub fn range(&self, total: usize) -> std::ops::Range<usize> {
        (self.index * total / self.count)..((self.index + 1) * total / self.count)
    }
}

/// What a run did.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct RunSummary {
    /// Samples of this run's shard made from nothing.
    pub made: usize,
    /// Samples of this run's shard redone because something of them was missing or wrong.
    pub repaired: usize,
    /// Samples of this run's shard found complete (every file matching its size and hash).
    pub kept: usize,
    /// What was wrong with each repaired sample (`00003: 00003_img2.png missing`).
    pub repairs: Vec<String>,
    /// Temporary files of dead writers removed at the start.
    pub stale_temporaries_removed: usize,
    /// Complete samples of the whole dataset after the run.
    pub complete: usize,
    pub total: usize,
    pub manifest_written: bool,
}

/// The seed of sample `index` under the master seed `master`: (config, seed, index) alone fix
/// a sample's bytes.
pub fn sample_seed(master: u64, index: usize) -> u64 {
    rng::derive(master, &[index as u64])
}

/// What became of one sample.
enum Outcome {
    Kept,
    Made,
    Repaired(SampleProblem),
}

/// A sample's images and optional flow before they are written.
struct Rendered {
    clean: [Image; 2],
    flow: Option<Flow>,
    layers: Option<Vec<crate::scene::layered::LayerRecord>>,
    source: Option<String>,
    draw: Option<crate::scene::ChairsDraw>,
}

/// The prepared generator: config, camera and (for dataset scenes) the discovered pairs.
pub struct Generator {
    config: GeneratorConfig,
    camera: Camera,
    psf_description: String,
    pairs: Vec<PairPaths>,
    total: usize,
}

impl Generator {
    /// Validates the config, loads the PSF, builds the camera, discovers dataset pairs.
    pub fn new(config: GeneratorConfig) -> Result<Self> {
        config.validate()?;
        let (psf, psf_description) = psf_source::load(&config.camera.psf)?;
        let camera = Camera::new(&config.camera, psf)?;
        let (pairs, total) = match &config.scene {
            SceneSpec::Chairs(chairs) => {
                // The photographs are read now, so that a missing or empty folder is refused
                // before any output folder is claimed.
                if let Some(photos) = &chairs.photos {
                    photos.library()?;
                }
                (Vec::new(), config.count)
            }
            SceneSpec::Dataset { path, layout } => {
                let pairs = discover(path, *layout)?;
                let total = config.count.min(pairs.len());
                (pairs, total)
            }
            _ => (Vec::new(), config.count),
        };
        Ok(Self {
            config,
            camera,
            psf_description,
            pairs,
            total,
        })
    }

    /// Number of samples the run will hold when complete.
    pub fn total(&self) -> usize {
        self.total
    }

    /// Camera stages that run, in order.
    pub fn stage_names(&self) -> Vec<&'static str> {
        self.camera.stage_names()
    }

    /// The seed of sample `index`.
    pub fn sample_seed(&self, index: usize) -> u64 {
        sample_seed(self.config.seed, index)
    }

    /// The bit depth of the written images.
    fn file_depth(&self) -> BitDepth {
        if self.config.camera.bit_depth == 16 {
            BitDepth::Sixteen
        } else {
            BitDepth::Eight
        }
    }

    /// Frame `k` (0 or 1) of a sample with seed `seed` through the camera, its noise drawn
    /// from the frame's own stream.
    fn observe(&self, clean: &Image, seed: u64, k: usize) -> Result<Image> {
        let purpose = [rng::purpose::NOISE_FRAME1, rng::purpose::NOISE_FRAME2][k];
        self.camera.apply(clean, rng::derive(seed, &[purpose]))
    }

    /// Sample `index` made in memory, as its files would read back: both frames through the
    /// camera and quantised to the file's bit depth, and the flow (`None` for a still pattern
    /// or a dataset pair without flow). Nothing is written; the bytes equal a written
    /// sample's.
    pub fn pair(&self, index: usize) -> Result<(Image, Image, Option<Flow>)> {
        if matches!(self.config.scene, SceneSpec::Dataset { .. }) && index >= self.total {
            return Err(Error::invalid(
                "sample index",
                format!("{index} is past the dataset's {} pairs", self.total),
            ));
        }
        let seed = self.sample_seed(index);
        let r = self.render(index, seed)?;
        let bits = match self.file_depth() {
            BitDepth::Eight => 8,
            BitDepth::Sixteen => 16,
        };
        let [a, b] = [0, 1].map(|k| {
            self.observe(&r.clean[k], seed, k).map(|mut img| {
                crate::imaging::tone::quantize(&mut img, bits);
                img
            })
        });
        Ok((a?, b?, r.flow))
    }

    /// The config this generator makes samples of.
    pub fn config(&self) -> &GeneratorConfig {
        &self.config
    }

    fn render(&self, index: usize, seed: u64) -> Result<Rendered> {
        let layered = |scene: crate::scene::LayeredScene| -> Result<Rendered> {
            let flow = if scene.is_static() {
                None
            } else {
                Some(scene.flow()?)
            };
            let clean = [scene.render(0)?, scene.render(1)?];
            Ok(Rendered {
                clean,
                flow,
                layers: Some(scene.records()),
                source: None,
                draw: None,
            })
        };
        match &self.config.scene {
            SceneSpec::Chairs(c) => {
                let (scene, draw) = c.build_recorded(seed)?;
                let mut r = layered(scene)?;
                r.draw = c.has_variety().then_some(draw);
                Ok(r)
            }
            SceneSpec::Movers(m) => layered(m.scene(seed)?),
            SceneSpec::Rocket { step, channels } => {
                layered(patterns::rocket(*step, *channels, patterns::S12_SIZE)?)
            }
            SceneSpec::Disc { radius, channels } => {
                layered(patterns::disc(*radius, *channels, patterns::S12_SIZE)?)
            }
            SceneSpec::Dataset { .. } => {
                let pair = &self.pairs[index];
                let (a, b) = io::read_image_pair(&pair.img1, &pair.img2)?;
                let flow = match &pair.flow {
                    Some(p) => {
                        let f = io::read_flow(p)?;
                        if (f.height(), f.width()) != (a.height(), a.width()) {
                            return Err(Error::shape(
                                format!("flow {}", p.display()),
                                format!("{}x{} (the images)", a.width(), a.height()),
                                format!("{}x{}", f.width(), f.height()),
                            ));
                        }
                        Some(f)
                    }
                    None => None,
                };
                Ok(Rendered {
                    clean: [a, b],
                    flow,
                    layers: None,
                    source: Some(pair.name.clone()),
                    draw: None,
                })
            }
        }
    }

    /// Keeps sample `index` of `dir` if it is complete (every file of its sidecar present with
    /// the recorded size and hash), and (re)makes it otherwise.
    fn sample(&self, dir: &Path, index: usize) -> Result<Outcome> {
        let meta_path = dir.join(SampleMeta::file_name(index));
        let seed = self.sample_seed(index);
        let outcome = match check_sample(dir, index, seed, Depth::Hashes) {
            Ok(_) => return Ok(Outcome::Kept),
            Err(p) if p.is_absent() => Outcome::Made,
            Err(p) => Outcome::Repaired(p),
        };
        let r = self.render(index, seed)?;
        let depth = self.file_depth();
        let mut files = Vec::new();
        for (k, clean) in r.clean.iter().enumerate() {
            let img = self.observe(clean, seed, k)?;
            let name = format!("{index:05}_img{}.png", k + 1);
            io::write_image(&dir.join(&name), &img, depth)?;
            files.push(record_file(dir, &name)?);
            if self.config.save_clean {
                let name = format!("{index:05}_clean{}.png", k + 1);
                io::write_image(&dir.join(&name), clean, BitDepth::Sixteen)?;
                files.push(record_file(dir, &name)?);
            }
        }
        let flow_stats = match &r.flow {
            Some(flow) => {
                let name = format!("{index:05}_flow.flo");
                io::write_flo(&dir.join(&name), flow)?;
                files.push(record_file(dir, &name)?);
                Some(FlowStats::of(flow))
            }
            None => None,
        };
        let (c, h, w) = r.clean[0].shape();
        let meta = SampleMeta {
            index,
            seed,
            width: w,
            height: h,
            channels: c,
            files,
            flow: flow_stats,
            source: r.source,
            layers: r.layers,
            scene_draw: r.draw,
        };
        meta.write(&meta_path)?;
        Ok(outcome)
    }

    /// Runs shard `shard` into `dir`: claims the folder for this config (or joins it, if it is
    /// this config's), keeps complete samples, makes missing ones, repairs broken ones, and
    /// writes `manifest.json` once every sample of the whole dataset is complete.
    ///
    /// Several runs of one config may work on one folder at once (shards, or reruns): they
    /// write identical bytes, each file by an atomic rename, and remove only the temporaries
    /// of writers that are gone. When the last shards finish together, each may write the
    /// manifest; its bytes are the same whoever writes it.
    pub fn run(&self, dir: &Path, shard: Shard, progress: bool) -> Result<RunSummary> {
        folder::claim(dir, &self.config)?;
        let stale_temporaries_removed =
            io::atomic::remove_stale_temporaries(dir, io::atomic::STALE_AFTER)?;
        let range = shard.range(self.total);
        let bar = if progress {
            let bar = ProgressBar::new(range.len() as u64);
            bar.set_style(
                ProgressStyle::with_template("{bar:40} {pos}/{len} samples  {elapsed} (eta {eta})")
                    .unwrap_or_else(|_| ProgressStyle::default_bar()),
            );
            bar
        } else {
            ProgressBar::hidden()
        };
        let done: Vec<Outcome> = range
            .clone()
            .into_par_iter()
            .map(|i| {
                let r = self.sample(dir, i);
                bar.inc(1);
                r
            })
            .collect::<Result<_>>()?;
        bar.finish_and_clear();
        let (mut made, mut kept, mut repairs) = (0, 0, Vec::new());
        for outcome in done {
            match outcome {
                Outcome::Kept => kept += 1,
                Outcome::Made => made += 1,
                Outcome::Repaired(p) => repairs.push(p.to_string()),
            }
        }
        // The manifest lists every sidecar as parsed from its file, whichever run wrote it, so
        // that its bytes do not depend on the shard split. This run's samples were just checked
        // or written; all are taken as complete when their files have the recorded sizes
        // (`--verify` reads every byte).
        let metas: Vec<Option<SampleMeta>> = (0..self.total)
            .into_par_iter()
            .map(|i| check_sample(dir, i, self.sample_seed(i), Depth::Sizes).ok())
            .collect();
        let complete = metas.iter().filter(|m| m.is_some()).count();
        let manifest_written = complete == self.total;
        if manifest_written {
            let manifest = Manifest {
                generator: format!("pins {}", env!("CARGO_PKG_VERSION")),
                config: self.config.clone(),
                count: self.total,
                stages: self.stage_names().iter().map(|s| s.to_string()).collect(),
                psf: self.psf_description.clone(),
                samples: metas.into_iter().flatten().collect(),
            };
            manifest.write(&dir.join("manifest.json"))?;
        }
        Ok(RunSummary {
            made,
            repaired: repairs.len(),
            kept,
            repairs,
            stale_temporaries_removed,
            complete,
            total: self.total,
            manifest_written,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_partition_the_indices() {
        assert!(Shard::parse("2/2").is_err());
        assert!(Shard::parse("x").is_err());
        let total = 10;
        let mut all: Vec<usize> = (0..3)
            .flat_map(|k| Shard { index: k, count: 3 }.range(total))
            .collect();
        all.sort();
        assert_eq!(all, (0..total).collect::<Vec<_>>());
        assert_eq!(
            Shard::parse(" 1 / 4").unwrap(),
            Shard { index: 1, count: 4 }
        );
    }

    /// A sample made in memory equals its files read back, bit for bit, through the full
    /// camera (noise, gamma, 8-bit) and at 16 bits; an index past a dataset's end is refused.
    #[test]
    fn pairs_in_memory_equal_written_samples() {
        for bit_depth in [8, 16] {
            let dir =
                std::env::temp_dir().join(format!("pins-pair-{}-{bit_depth}", std::process::id()));
            let _ = std::fs::remove_dir_all(&dir);
            let config = GeneratorConfig {
                count: 3,
                seed: 11,
                scene: SceneSpec::Chairs(crate::scene::ChairsConfig {
                    width: 48,
                    height: 40,
                    sprites: [1, 2],
                    supersample: 1,
                    ..crate::scene::ChairsConfig::default()
                }),
                camera: crate::imaging::CameraConfig {
                    bit_depth,
                    ..crate::imaging::CameraConfig::default()
                },
                save_clean: false,
            };
            let generator = Generator::new(config).expect("generator");
            generator.run(&dir, Shard::ALL, false).expect("generate");
            for i in 0..3 {
                let (a, b, flow) = generator.pair(i).expect("pair");
                let (ra, rb) = io::read_image_pair(
                    &dir.join(format!("{i:05}_img1.png")),
                    &dir.join(format!("{i:05}_img2.png")),
                )
                .expect("read");
                assert_eq!(
                    a.data(),
                    ra.data(),
                    "frame 1 of sample {i}, {bit_depth} bits"
                );
                assert_eq!(
                    b.data(),
                    rb.data(),
                    "frame 2 of sample {i}, {bit_depth} bits"
                );
                let rf = io::read_flow(&dir.join(format!("{i:05}_flow.flo"))).expect("flow");
                let f = flow.expect("a moving scene has flow");
                assert_eq!(f.u(), rf.u());
                assert_eq!(f.v(), rf.v());
            }
            let _ = std::fs::remove_dir_all(&dir);
        }
    }
}
