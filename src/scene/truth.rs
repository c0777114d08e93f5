//! Ground-truth object centres of a trajectory clip (`truth.json`), the reference of the
//! Table S5 errors: one centre per object per frame and whether the object is wholly in view.

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::trajectory::TrajectoryConfig;
use crate::error::{Error, Result};

/// One object's ground truth.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TruthObject {
    pub index: usize,
    pub radius: f64,
    /// Centre `[x, y]` in pixels at every frame (it may lie outside the frame).
    pub centroids: Vec<[f64; 2]>,
    /// Whether the object lies wholly inside each frame.
    pub visible: Vec<bool>,
}

/// `truth.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Truth {
    pub width: usize,
    pub height: usize,
    pub fps: f64,
    pub frames: usize,
    pub objects: Vec<TruthObject>,
}

impl Truth {
    /// The ground truth of a scene.
    pub fn of(scene: &TrajectoryConfig) -> Result<Self> {
        scene.validate()?;
        Ok(Self {
            width: scene.width,
            height: scene.height,
            fps: scene.fps,
            frames: scene.frames,
            objects: (0..scene.objects.len())
                .map(|i| TruthObject {
                    index: i,
                    radius: scene.objects[i].radius,
                    centroids: (0..scene.frames)
                        .map(|n| {
                            let (x, y) = scene.centroid(i, n);
                            [x, y]
                        })
                        .collect(),
                    visible: (0..scene.frames).map(|n| scene.visible(i, n)).collect(),
                })
                .collect(),
        })
    }

    /// The truth of every `step`-th frame (0, step, 2·step, …): what a tracker that keeps one
    /// camera frame in `step` sees, at `fps / step`.
    pub fn every(&self, step: usize) -> Self {
        let step = step.max(1);
        Self {
            width: self.width,
            height: self.height,
            fps: self.fps / step as f64,
            frames: self.frames.div_ceil(step),
            objects: self
                .objects
                .iter()
                .map(|o| TruthObject {
                    index: o.index,
                    radius: o.radius,
                    centroids: o.centroids.iter().step_by(step).copied().collect(),
                    visible: o.visible.iter().step_by(step).copied().collect(),
                })
                .collect(),
        }
    }

    /// Reads and checks a `truth.json`.
    pub fn read(path: &Path) -> Result<Self> {
        let t: Self = crate::io::read_json(path)?;
        t.validate().map_err(|e| crate::io::in_config(path, e))?;
        Ok(t)
    }

    /// Every object has one finite centre and one visibility flag per frame.
    pub fn validate(&self) -> Result<()> {
        if self.frames == 0 || self.objects.is_empty() {
            return Err(Error::invalid(
                "truth",
                "needs frames and at least one object",
            ));
        }
        for o in &self.objects {
            if o.centroids.len() != self.frames || o.visible.len() != self.frames {
                return Err(Error::invalid(
                    format!("truth object {}", o.index),
                    format!(
                        "has {} centres and {} visibility flags for {} frames",
                        o.centroids.len(),
                        o.visible.len(),
                        self.frames
                    ),
                ));
            }
            if o.centroids.iter().flatten().any(|v| !v.is_finite()) {
                return Err(Error::invalid(
                    format!("truth object {}", o.index),
                    "a centre is not finite",
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn truth(frames: usize) -> Truth {
        Truth {
            width: 64,
            height: 48,
            fps: 15.0,
            frames,
            objects: vec![TruthObject {
                index: 0,
                radius: 4.0,
                centroids: (0..frames).map(|n| [n as f64, 2.0 * n as f64]).collect(),
                visible: (0..frames).map(|n| n % 2 == 0).collect(),
            }],
        }
    }

    #[test]
    fn every_kth_frame_keeps_frames_0_k_2k() {
        let t = truth(10).every(3);
        assert_eq!((t.frames, t.fps), (4, 5.0));
        let o = &t.objects[0];
        assert_eq!(
            o.centroids,
            vec![[0.0, 0.0], [3.0, 6.0], [6.0, 12.0], [9.0, 18.0]]
        );
        assert_eq!(o.visible, vec![true, false, true, false]);
        assert!(t.validate().is_ok());
        assert_eq!(truth(10).every(1), truth(10));
        assert_eq!(truth(10).every(0), truth(10));
    }
}
