//! Layered scenes: a background and sprites, each a textured shape with its own affine pose in
//! frame 1 and frame 2, rendered with correct occlusion and exact forward flow (FlyingChairs).

use std::sync::Arc;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::affine::Affine;
use super::shape::Shape;
use super::texture::add_bilinear;
use crate::error::{Error, Result};
use crate::types::{Flow, Image};

/// What a layer is painted with.
#[derive(Clone, Debug)]
pub enum Fill {
    /// One colour (one value per channel).
    Flat(Vec<f32>),
    /// A raster, addressed by local coordinates plus `origin` (the raster pixel at local 0, 0).
    Texture {
        image: Arc<Image>,
        origin: (f64, f64),
    },
}

/// One layer: a shape in local coordinates, its fill, and its pose in each of the two frames.
#[derive(Clone, Debug)]
pub struct Layer {
    pub shape: Shape,
    pub fill: Fill,
    /// Local → image coordinates in frame 1 and frame 2.
    pub poses: [Affine; 2],
}

/// Serialisable record of a layer's geometry, for manifests.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LayerRecord {
    pub shape: Shape,
    pub poses: [Affine; 2],
}

/// Layers bottom to top over a `width × height` frame with `channels` channels.
#[derive(Clone, Debug)]
pub struct LayeredScene {
    pub width: usize,
    pub height: usize,
    pub channels: usize,
    pub layers: Vec<Layer>,
    /// Samples per pixel side for anti-aliased edges (1 = none).
    pub supersample: usize,
}

/// A layer ready for rendering: inverse poses and a bounding circle in image coordinates.
struct Prepared<'a> {
    layer: &'a Layer,
    inverse: [Affine; 2],
    centre: [(f64, f64); 2],
    bound: [f64; 2],
}

impl LayeredScene {
    /// Checks sizes and that every pose can be inverted.
    pub fn validate(&self) -> Result<()> {
        if self.width == 0 || self.height == 0 {
            return Err(Error::invalid(
                "scene size",
                format!("{}x{} has no pixels", self.width, self.height),
            ));
        }
        if self.channels != 1 && self.channels != 3 {
            return Err(Error::invalid(
                "scene channels",
                format!("must be 1 or 3, got {}", self.channels),
            ));
        }
        self.prepare().map(|_| ())
    }

    fn prepare(&self) -> Result<Vec<Prepared<'_>>> {
        self.layers
            .iter()
            .enumerate()
            .map(|(i, layer)| {
                let inv = |k: usize| {
                    layer.poses[k].inverse().ok_or_else(|| {
                        Error::invalid(
                            format!("layer {i} pose in frame {}", k + 1),
                            "singular transform",
                        )
                    })
                };
                let scale = |p: &Affine| {
                    // The largest singular value bounds how far a local radius can stretch.
                    let s = (p.a * p.a + p.b * p.b + p.c * p.c + p.d * p.d).sqrt();
                    s * layer.shape.bound_radius()
                };
                Ok(Prepared {
                    layer,
                    inverse: [inv(0)?, inv(1)?],
                    centre: [
                        layer.poses[0].apply(0.0, 0.0),
                        layer.poses[1].apply(0.0, 0.0),
                    ],
                    bound: [scale(&layer.poses[0]), scale(&layer.poses[1])],
                })
            })
            .collect()
    }

    /// The layer visible at image point (x, y) in `frame` (0 or 1), with its local coordinates.
    fn hit<'a>(
        prepared: &'a [Prepared<'a>],
        frame: usize,
        x: f64,
        y: f64,
    ) -> Option<(&'a Prepared<'a>, f64, f64)> {
        prepared.iter().rev().find_map(|p| {
            let (cx, cy) = p.centre[frame];
            let b = p.bound[frame];
            if b.is_finite() && ((x - cx).abs() > b || (y - cy).abs() > b) {
                return None;
            }
            let (lx, ly) = p.inverse[frame].apply(x, y);
            p.layer.shape.contains(lx, ly).then_some((p, lx, ly))
        })
    }

    fn colour(&self, layer: &Layer, lx: f64, ly: f64, out: &mut [f32]) {
        match &layer.fill {
            Fill::Flat(c) => {
                for (o, v) in out.iter_mut().zip(c.iter().cycle()) {
                    *o += v;
                }
            }
            Fill::Texture { image, origin } => {
                let (tx, ty) = ((lx + origin.0) as f32, (ly + origin.1) as f32);
                add_bilinear(image, tx, ty, out);
            }
        }
    }

    /// Renders frame `frame` (0 = first, 1 = second) as linear intensity `[C, H, W]`.
    pub fn render(&self, frame: usize) -> Result<Image> {
        let prepared = self.prepare()?;
        let (w, h, ch, s) = (
            self.width,
            self.height,
            self.channels,
            self.supersample.max(1),
        );
        let inv_s2 = 1.0 / (s * s) as f32;
        let rows: Vec<Vec<f32>> = (0..h)
            .into_par_iter()
            .map(|y| {
                let mut row = vec![0.0f32; ch * w];
                let mut acc = vec![0.0f32; ch];
                for x in 0..w {
                    acc.iter_mut().for_each(|v| *v = 0.0);
                    for sy in 0..s {
                        for sx in 0..s {
                            // Sub-sample centres inside the pixel's square [x − ½, x + ½].
                            let px = x as f64 + (sx as f64 + 0.5) / s as f64 - 0.5;
                            let py = y as f64 + (sy as f64 + 0.5) / s as f64 - 0.5;
                            if let Some((p, lx, ly)) = Self::hit(&prepared, frame, px, py) {
                                self.colour(p.layer, lx, ly, &mut acc);
                            }
                        }
                    }
                    for c in 0..ch {
                        row[c * w + x] = (acc[c] * inv_s2).clamp(0.0, 1.0);
                    }
                }
                row
            })
            .collect();
        let n = w * h;
        let mut data = vec![0.0f32; ch * n];
        for (y, row) in rows.iter().enumerate() {
            for c in 0..ch {
                data[c * n + y * w..c * n + (y + 1) * w].copy_from_slice(&row[c * w..(c + 1) * w]);
            }
        }
        Image::from_vec(ch, h, w, data)
    }

    /// Exact forward flow from frame 1 to frame 2 at every pixel centre: the motion of the
    /// layer visible there in frame 1 (zero where no layer covers the pixel).
    pub fn flow(&self) -> Result<Flow> {
        let prepared = self.prepare()?;
        let (w, h) = (self.width, self.height);
        let rows: Vec<Vec<(f32, f32)>> = (0..h)
            .into_par_iter()
            .map(|y| {
                (0..w)
                    .map(|x| {
                        let (px, py) = (x as f64, y as f64);
                        match Self::hit(&prepared, 0, px, py) {
                            Some((p, lx, ly)) => {
                                let (x2, y2) = p.layer.poses[1].apply(lx, ly);
                                ((x2 - px) as f32, (y2 - py) as f32)
                            }
                            None => (0.0, 0.0),
                        }
                    })
                    .collect()
            })
            .collect();
        let mut flow = Flow::zeros(h, w);
        for (y, row) in rows.iter().enumerate() {
            for (x, &(u, v)) in row.iter().enumerate() {
                flow.set(y, x, u, v);
            }
        }
        Ok(flow)
    }

    /// True when no layer moves between the frames (the scene needs no flow).
    pub fn is_static(&self) -> bool {
        self.layers.iter().all(|l| l.poses[0] == l.poses[1])
    }

    /// Geometry of every layer, for manifests.
    pub fn records(&self) -> Vec<LayerRecord> {
        self.layers
            .iter()
            .map(|l| LayerRecord {
                shape: l.shape.clone(),
                poses: l.poses,
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two_layer_scene() -> LayeredScene {
        let bg = Layer {
            shape: Shape::Full,
            fill: Fill::Flat(vec![0.1]),
            poses: [Affine::IDENTITY; 2],
        };
        let square = Layer {
            shape: Shape::Polygon {
                vertices: vec![(-4.0, -4.0), (4.0, -4.0), (4.0, 4.0), (-4.0, 4.0)],
            },
            fill: Fill::Flat(vec![0.9]),
            poses: [
                Affine::translation(10.0, 10.0),
                Affine::translation(13.0, 8.0),
            ],
        };
        LayeredScene {
            width: 32,
            height: 24,
            channels: 1,
            layers: vec![bg, square],
            supersample: 1,
        }
    }

    #[test]
    fn flow_is_that_of_the_visible_layer() {
        let scene = two_layer_scene();
        let flow = scene.flow().unwrap();
        assert_eq!(flow.get(10, 10), (3.0, -2.0));
        assert_eq!(flow.get(0, 0), (0.0, 0.0));
        // Brightness constancy: frame 2 at x + flow equals frame 1 at x on the sprite.
        let (f1, f2) = (scene.render(0).unwrap(), scene.render(1).unwrap());
        assert_eq!(f1.get(0, 10, 10), 0.9);
        assert_eq!(f2.get(0, 8, 13), 0.9);
        assert_eq!(f2.get(0, 10, 7), 0.1); // uncovered background
    }

    #[test]
    fn rotation_flow_matches_pose_difference() {
        let mut scene = two_layer_scene();
        scene.layers[1].poses[1] = Affine::pose(10.0, 10.0, 0.1, 1.05);
        let flow = scene.flow().unwrap();
        let (u, v) = flow.get(12, 13);
        let (x2, y2) = Affine::pose(10.0, 10.0, 0.1, 1.05).apply(3.0, 2.0);
        assert!((u as f64 - (x2 - 13.0)).abs() < 1e-5 && (v as f64 - (y2 - 12.0)).abs() < 1e-5);
    }

    #[test]
    fn supersampling_antialiases_edges_and_static_scenes_are_detected() {
        let mut scene = two_layer_scene();
        scene.supersample = 4;
        let f1 = scene.render(0).unwrap();
        // Pixel (x=14) is half covered: the square spans x ∈ [6, 14].
        let v = f1.get(0, 10, 14);
        assert!(v > 0.2 && v < 0.8, "{v}");
        assert!(!scene.is_static());
        scene.layers[1].poses[1] = scene.layers[1].poses[0];
        assert!(scene.is_static());
    }
}
