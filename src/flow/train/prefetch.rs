//! Loading the batches of the coming steps on worker threads while the current step runs
//! (Note S11's training loop, fed ahead): a step's examples are a function of (seed, step)
//! alone ([`super::step::examples`]), so loading them early changes nothing but the wait. On a
//! GPU the decoding and cropping of a batch of PNG pairs, or the making of a stream's, otherwise
//! takes as long as the step or longer.

use std::collections::VecDeque;
use std::sync::Arc;
use std::thread::JoinHandle;

use super::config::TrainConfig;
use super::source::TrainData;
use super::step;
use crate::error::{Error, Result};
use crate::flow::data::Example;

/// The batches of steps `next − queue.len() .. next`, each loading on its own thread.
pub struct Prefetch {
    config: Arc<TrainConfig>,
    data: Arc<TrainData>,
    queue: VecDeque<(usize, JoinHandle<Result<Vec<Example>>>)>,
    /// The next step to start loading.
    next: usize,
    /// One past the last step of this session.
    stop: usize,
    depth: usize,
}

impl Prefetch {
    /// Starts loading steps `start..` (at most `depth` at a time, at least one) up to `stop`.
    pub fn new(
        config: &TrainConfig,
        data: &TrainData,
        start: usize,
        stop: usize,
        depth: usize,
    ) -> Self {
        let mut prefetch = Self {
            config: Arc::new(config.clone()),
            data: Arc::new(data.clone()),
            queue: VecDeque::new(),
            next: start,
            stop,
            depth: depth.max(1),
        };
        prefetch.fill();
        prefetch
    }

    /// The number of batches loaded ahead on this machine: one per core up to 16 (a step
    /// needs one batch; on a GPU fed by a stream, making a batch takes a core several times
    /// as long as the step, so every core makes one).
    pub fn default_depth() -> usize {
        std::thread::available_parallelism()
            .map_or(2, |n| n.get())
            .clamp(2, 16)
    }

    fn fill(&mut self) {
        while self.queue.len() < self.depth && self.next < self.stop {
            let (config, set, s) = (self.config.clone(), self.data.clone(), self.next);
            let handle = std::thread::spawn(move || step::examples(&config, &set, s));
            self.queue.push_back((self.next, handle));
            self.next += 1;
        }
    }

    /// The examples of step `step`, which must be the next step not yet taken (the loop asks
    /// in order; anything else is a bug, reported rather than loaded out of turn).
    pub fn take(&mut self, step: usize) -> Result<Vec<Example>> {
        match self.queue.pop_front() {
            Some((s, handle)) if s == step => {
                self.fill();
                handle
                    .join()
                    .unwrap_or_else(|_| Err(Error::invalid("training", "loading a batch panicked")))
            }
            _ => Err(Error::invalid(
                "training",
                format!("the batch of step {step} was asked out of order"),
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The prefetched batches are exactly the ones loaded in the step, in order, and stop at
    /// `stop`.
    #[test]
    fn prefetched_batches_equal_direct_ones() {
        let dir = std::env::temp_dir().join(format!("pins-prefetch-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let generator = crate::dataset::GeneratorConfig {
            count: 6,
            seed: 5,
            scene: crate::dataset::SceneSpec::Chairs(crate::scene::ChairsConfig {
                width: 80,
                height: 64,
                sprites: [1, 2],
                supersample: 1,
                ..crate::scene::ChairsConfig::default()
            }),
            camera: crate::imaging::CameraConfig::ideal(),
            save_clean: false,
        };
        crate::dataset::Generator::new(generator)
            .expect("generator")
            .run(&dir, crate::dataset::Shard::ALL, false)
            .expect("generate");
        let config = TrainConfig {
            batch_size: 3,
            crop: [32, 48],
            ..TrainConfig::default()
        };
        let set = TrainData::open(&dir, &config).expect("open");
        let mut prefetch = Prefetch::new(&config, &set, 2, 7, 3);
        for s in 2..7 {
            let a = prefetch.take(s).expect("prefetched");
            let b = step::examples(&config, &set, s).expect("direct");
            assert_eq!(a.len(), 3);
            for (x, y) in a.iter().zip(&b) {
                assert_eq!(x.img1, y.img1);
                assert_eq!(x.img2, y.img2);
                assert_eq!(x.flow, y.flow);
                assert_eq!(x.valid, y.valid);
            }
        }
        assert!(prefetch.queue.is_empty(), "nothing is loaded past stop");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
