//! Training pairs of the trajectory scenes (Movies S1–S2, Table S5): textured discs over a still
//! textured background, each disc's texture drawn from the same procedural family as the
//! background's, so that a mover is told from what it moves over by its motion more than by
//! its look (camouflage). One pair per seed: the number of discs, their radii, positions,
//! directions and speeds are drawn, and the pair is the two-frame [`TrajectoryConfig`] of
//! straight paths between them (two frames of any path are a translation of each disc).

use std::f64::consts::PI;

use rand::RngExt;
use serde::{Deserialize, Serialize};

use super::layered::LayeredScene;
use super::trajectory::{ObjectSpec, PathKind, TrajectoryConfig};
use crate::error::{Error, Result};
use crate::rng;

/// The draw of a pair of mover scenes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MoversConfig {
    pub width: usize,
    pub height: usize,
    /// Number of discs, drawn uniformly in [min, max].
    pub discs: [usize; 2],
    /// Disc radius in pixels, drawn log-uniformly in [min, max].
    pub radius_px: [f64; 2],
    /// Each disc's motion between the two frames in pixels, drawn log-uniformly in [min, max]
    /// (the tracking clips' discs move 1–8 px a frame at 30 fps, twice that at 15).
    pub speed_px: [f64; 2],
}

impl Default for MoversConfig {
    fn default() -> Self {
        Self {
            width: 512,
            height: 384,
            discs: [1, 5],
            radius_px: [4.0, 24.0],
            speed_px: [0.3, 24.0],
        }
    }
}

impl MoversConfig {
    pub fn validate(&self) -> Result<()> {
        let sides = (32..=8192).contains(&self.width) && (32..=8192).contains(&self.height);
        if !sides {
            return Err(Error::invalid(
                "scene",
                format!(
                    "frame sides must be 32..=8192, got {}x{}",
                    self.width, self.height
                ),
            ));
        }
        if !(1 <= self.discs[0] && self.discs[0] <= self.discs[1] && self.discs[1] <= 64) {
            return Err(Error::invalid(
                "scene.discs",
                format!(
                    "must be [min, max] with 1 <= min <= max <= 64, got {:?}",
                    self.discs
                ),
            ));
        }
        for (key, [lo, hi]) in [
            ("scene.radius_px", self.radius_px),
            ("scene.speed_px", self.speed_px),
        ] {
            if !(lo > 0.0 && lo <= hi && hi.is_finite()) {
                return Err(Error::invalid(
                    key,
                    format!("must be [min, max] with 0 < min <= max, finite, got [{lo}, {hi}]"),
                ));
            }
        }
        // A disc's centre is drawn in [r, side − 1 − r]: that range must not be empty.
        let side = self.width.min(self.height) as f64;
        if self.radius_px[0] <= 1.0 || 2.0 * self.radius_px[1] >= side - 1.0 {
            return Err(Error::invalid(
                "scene.radius_px",
                format!(
                    "radii must be > 1 px and fit a {}x{} frame, got {:?}",
                    self.width, self.height, self.radius_px
                ),
            ));
        }
        Ok(())
    }

    /// The two-frame trajectory scene of `seed`: every disc whole inside the first frame.
    pub fn trajectory(&self, seed: u64) -> Result<TrajectoryConfig> {
        self.validate()?;
        let mut r = rng::stream(seed, &[rng::purpose::SCENE, 91]);
        let (w, h) = (self.width as f64, self.height as f64);
        let log_uniform = |r: &mut rng::Rng, [lo, hi]: [f64; 2]| {
            if hi > lo {
                (r.random_range(lo.ln()..hi.ln())).exp()
            } else {
                lo
            }
        };
        let count = r.random_range(self.discs[0]..=self.discs[1]);
        let objects = (0..count)
            .map(|_| {
                let radius = log_uniform(&mut r, self.radius_px);
                let x = r.random_range(radius..w - 1.0 - radius);
                let y = r.random_range(radius..h - 1.0 - radius);
                let (s, a) = (
                    log_uniform(&mut r, self.speed_px),
                    r.random_range(0.0..2.0 * PI),
                );
                ObjectSpec {
                    path: PathKind::Line,
                    radius,
                    from: [x / w, y / h],
                    to: [(x + s * a.cos()) / w, (y + s * a.sin()) / h],
                    start: 0.0,
                    rate: 1.0,
                }
            })
            .collect();
        Ok(TrajectoryConfig {
            width: self.width,
            height: self.height,
            fps: 30.0,
            frames: 2,
            objects,
            seed: r.random(),
        })
    }

    /// The layered two-frame scene of `seed`.
    pub fn scene(&self, seed: u64) -> Result<LayeredScene> {
        self.trajectory(seed)?.pair(0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small() -> MoversConfig {
        MoversConfig {
            width: 96,
            height: 64,
            discs: [2, 3],
            radius_px: [4.0, 8.0],
            speed_px: [1.0, 6.0],
        }
    }

    /// Every disc moves by its drawn speed, in the flow as on its path, and starts whole
    /// inside the frame; the same seed draws the same pair and another seed another one.
    #[test]
    fn each_disc_moves_by_its_drawn_speed_and_the_seed_fixes_the_pair() {
        let cfg = small();
        for seed in 0..20 {
            let t = cfg.trajectory(seed).unwrap();
            assert!((2..=3).contains(&t.objects.len()));
            for (i, o) in t.objects.iter().enumerate() {
                assert!(
                    (4.0..=8.0).contains(&o.radius) && t.visible(i, 0),
                    "seed {seed}"
                );
                let (a, b) = (t.centroid(i, 0), t.centroid(i, 1));
                let s = (b.0 - a.0).hypot(b.1 - a.1);
                assert!(
                    (1.0 - 1e-9..=6.0 + 1e-9).contains(&s),
                    "seed {seed}: {s} px"
                );
            }
        }
        let t = cfg.trajectory(3).unwrap();
        let top = t.objects.len() - 1; // drawn last, nothing occludes it
        let flow = cfg.scene(3).unwrap().flow().unwrap();
        let (a, b) = (t.centroid(top, 0), t.centroid(top, 1));
        let (u, v) = flow.get(a.1.round() as usize, a.0.round() as usize);
        assert!((u as f64 - (b.0 - a.0)).abs() < 1e-3 && (v as f64 - (b.1 - a.1)).abs() < 1e-3);
        assert_eq!(cfg.trajectory(3).unwrap(), t);
        assert_ne!(cfg.trajectory(4).unwrap(), t);
    }

    #[test]
    fn a_draw_that_cannot_be_made_is_refused_by_name() {
        let bad = |c: MoversConfig| c.validate().unwrap_err().to_string();
        assert!(
            bad(MoversConfig {
                discs: [0, 2],
                ..small()
            })
            .contains("scene.discs")
        );
        assert!(
            bad(MoversConfig {
                discs: [3, 2],
                ..small()
            })
            .contains("scene.discs")
        );
        assert!(
            bad(MoversConfig {
                speed_px: [0.0, 2.0],
                ..small()
            })
            .contains("scene.speed_px")
        );
        assert!(
            bad(MoversConfig {
                radius_px: [4.0, 40.0],
                ..small()
            })
            .contains("scene.radius_px")
        );
        assert!(
            bad(MoversConfig {
                speed_px: [1.0, f64::NAN],
                ..small()
            })
            .contains("scene.speed_px")
        );
        assert!(
            bad(MoversConfig {
                width: 8,
                ..small()
            })
            .contains("32..=8192")
        );
        // The largest disc whose centre still has room in a 64-row frame, and one past it.
        let fits = MoversConfig {
            radius_px: [4.0, 31.4],
            discs: [5, 5],
            ..small()
        };
        assert!((0..20).all(|seed| fits.trajectory(seed).is_ok()));
        let past = MoversConfig {
            radius_px: [4.0, 31.6],
            ..small()
        };
        assert!(bad(past).contains("scene.radius_px"));
    }
}
