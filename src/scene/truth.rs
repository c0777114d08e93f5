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
