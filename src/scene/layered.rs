//! Layered scenes: a background and sprites, each a textured shape with its own pose (affine,
//! or a plane's perspective) in frame 1 and frame 2, rendered with correct occlusion and exact
//! forward flow (FlyingChairs; a road under a moving camera, as in KITTI).

use std::sync::Arc;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::pose::Pose;
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
    pub poses: [Pose; 2],
}

/// Serialisable record of a layer's geometry, for manifests.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LayerRecord {
    pub shape: Shape,
    pub poses: [Pose; 2],
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

/// A layer ready for rendering: inverse poses and, per frame, a box in image coordinates
/// `[x_min, x_max, y_min, y_max]` outside which the layer shows nowhere (`None`: unbounded).
struct Prepared<'a> {
    layer: &'a Layer,
    inverse: [Pose; 2],
    bounds: [Option<[f64; 4]>; 2],
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
                let name = |k: usize| format!("layer {i} pose in frame {}", k + 1);
                for k in 0..2 {
                    check_in_front(layer, k).map_err(|why| Error::invalid(name(k), why))?;
                }
                let inv = |k: usize| {
                    layer.poses[k]
                        .inverse()
                        .ok_or_else(|| Error::invalid(name(k), "singular transform"))
                };
                Ok(Prepared {
                    layer,
                    inverse: [inv(0)?, inv(1)?],
                    bounds: [image_bounds(layer, 0), image_bounds(layer, 1)],
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
            if let Some([x0, x1, y0, y1]) = p.bounds[frame]
                && (x < x0 || x > x1 || y < y0 || y > y1)
            {
                return None;
            }
            let (lx, ly) = p.inverse[frame].apply(x, y)?;
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
                                // In front in frame 2 wherever the layer is (`check_in_front`).
                                let (x2, y2) = p.layer.poses[1].apply(lx, ly).unwrap_or((px, py));
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

/// Where the layer's shape can show in frame `k`: for an affine pose, the square of its bound
/// radius's reach about the origin's image; for a polygon wholly in front of a homography's
/// camera (`check_in_front`), the box of its vertices' images (in front of the camera a
/// homography keeps straight lines straight, so every edge's image lies between its ends'),
/// widened by 1e-6 px against rounding; else unbounded.
fn image_bounds(layer: &Layer, k: usize) -> Option<[f64; 4]> {
    let pose = &layer.poses[k];
    match (pose, &layer.shape) {
        (Pose::Affine(a), shape) => {
            let r = pose.reach(shape.bound_radius());
            let (cx, cy) = a.apply(0.0, 0.0);
            r.is_finite().then_some([cx - r, cx + r, cy - r, cy + r])
        }
        (Pose::Projective(h), Shape::Polygon { vertices }) => {
            let mut b = [
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
            ];
            for &(u, v) in vertices {
                let (x, y) = h.apply(u, v)?;
                b = [b[0].min(x), b[1].max(x), b[2].min(y), b[3].max(y)];
            }
            let pad = 1e-6;
            b.iter().all(|v| v.is_finite()).then_some([
                b[0] - pad,
                b[1] + pad,
                b[2] - pad,
                b[3] + pad,
            ])
        }
        _ => None,
    }
}

/// A layer under a homography must lie wholly in front of the camera in frame `k`: its shape a
/// polygon (a plane's finite patch) whose every vertex has an image. Affine layers always do.
fn check_in_front(layer: &Layer, k: usize) -> std::result::Result<(), String> {
    let pose = &layer.poses[k];
    if let Pose::Affine(_) = pose {
        return Ok(());
    }
    match &layer.shape {
        Shape::Polygon { vertices } if pose.in_front(vertices) => Ok(()),
        Shape::Polygon { .. } => Err("part of the plane's patch lies beyond the horizon".into()),
        _ => Err("a homography needs a polygon (the plane's finite patch)".into()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::affine::Affine;
    use crate::scene::pose::Homography;

    fn two_layer_scene() -> LayeredScene {
        let bg = Layer {
            shape: Shape::Full,
            fill: Fill::Flat(vec![0.1]),
            poses: [Pose::IDENTITY; 2],
        };
        let square = Layer {
            shape: Shape::Polygon {
                vertices: vec![(-4.0, -4.0), (4.0, -4.0), (4.0, 4.0), (-4.0, 4.0)],
            },
            fill: Fill::Flat(vec![0.9]),
            poses: [
                Affine::translation(10.0, 10.0).into(),
                Affine::translation(13.0, 8.0).into(),
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
        scene.layers[1].poses[1] = Affine::pose(10.0, 10.0, 0.1, 1.05).into();
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

    /// A ground plane (X right, Z ahead, metres) under a camera 1.5 m up with focal length
    /// 20 px and the horizon at row 6, for a camera moved `tz` metres ahead: x = 16 + 20 X/Z,
    /// y = 6 + 30/Z.
    fn ground(tz: f64) -> Homography {
        Homography {
            m: [
                20.0,
                16.0,
                -16.0 * tz,
                0.0,
                6.0,
                30.0 - 6.0 * tz,
                0.0,
                1.0,
                -tz,
            ],
        }
    }

    /// The plane's patch X in [-4, 4], Z in [1.5, 12] over a flat sky: the flow is the two
    /// homographies' difference, frame 2 shows at x + flow what frame 1 shows at x (the
    /// ground's texture is a ramp in Z, so every row differs), and above the patch's far edge
    /// the sky shows through.
    #[test]
    fn a_ground_plane_moves_by_its_homography_and_ends_at_its_far_edge() {
        let mut ramp = Image::zeros(1, 64, 8);
        for y in 0..64 {
            ramp.plane_mut(0)[y * 8..(y + 1) * 8].fill(y as f32 / 64.0);
        }
        let ground_layer = Layer {
            shape: Shape::Polygon {
                vertices: vec![(-4.0, 1.5), (4.0, 1.5), (4.0, 12.0), (-4.0, 12.0)],
            },
            fill: Fill::Flat(vec![0.5]),
            poses: [ground(0.0).into(), ground(0.5).into()],
        };
        let sky = Layer {
            shape: Shape::Full,
            fill: Fill::Flat(vec![0.9]),
            poses: [Pose::IDENTITY; 2],
        };
        let mut scene = LayeredScene {
            width: 32,
            height: 24,
            channels: 1,
            layers: vec![sky, ground_layer],
            supersample: 1,
        };
        let flow = scene.flow().unwrap();
        // Row 20 sees Z = 30 / 14; a camera 0.5 m ahead sees it at y = 6 + 30 / (Z − 0.5).
        let z = 30.0 / 14.0;
        let (u, v) = flow.get(20, 16);
        assert!(
            u.abs() < 1e-4 && (v as f64 - (30.0 / (z - 0.5) - 14.0)).abs() < 1e-4,
            "{v}"
        );
        // Row 7 (Z = 30) is beyond the patch: the still sky.
        assert_eq!(flow.get(7, 16), (0.0, 0.0));
        let f1 = scene.render(0).unwrap();
        assert_eq!((f1.get(0, 20, 16), f1.get(0, 7, 16)), (0.5, 0.9));
        // Brightness constancy on a textured ground: local (X, 5.3 Z), texture pixel
        // (X + 4, 5.3 (Z − 1.5)).
        let stretch = Homography {
            m: [1.0, 0.0, 0.0, 0.0, 1.0 / 5.3, 0.0, 0.0, 0.0, 1.0],
        };
        scene.layers[1] = Layer {
            shape: Shape::Polygon {
                vertices: vec![(-4.0, 7.95), (4.0, 7.95), (4.0, 63.6), (-4.0, 63.6)],
            },
            fill: Fill::Texture {
                image: Arc::new(ramp),
                origin: (4.0, -7.95),
            },
            poses: [
                ground(0.0).compose(&stretch).into(),
                ground(0.5).compose(&stretch).into(),
            ],
        };
        let (f1, f2) = (scene.render(0).unwrap(), scene.render(1).unwrap());
        let flow = scene.flow().unwrap();
        // Rows 12, 16, 18 see Z = 5, 3, 2.5 and move 0.67, 2 and 3 rows down.
        for (y, want) in [(12usize, 6.0 + 30.0 / 4.5 - 12.0), (16, 2.0), (18, 3.0)] {
            let (u, v) = flow.get(y, 16);
            assert!(
                u.abs() < 1e-4 && (v as f64 - want).abs() < 1e-4,
                "row {y}: {v}"
            );
            // Frame 2 between its rows, linearly.
            let y2 = y as f64 + v as f64;
            let (y0, t) = (y2.floor() as usize, (y2 - y2.floor()) as f32);
            let b = f2.get(0, y0, 16) * (1.0 - t) + f2.get(0, y0 + 1, 16) * t;
            let a = f1.get(0, y, 16);
            assert!((b - a).abs() < 0.02, "row {y}: {b} vs {a}");
            assert!(
                (f2.get(0, y, 16) - a).abs() > 0.01,
                "row {y}: the ramp moved"
            );
        }
    }

    /// A homography on an unbounded shape, or a patch reaching beyond the horizon, is refused.
    #[test]
    fn a_plane_beyond_its_horizon_is_refused() {
        let mut scene = two_layer_scene();
        scene.layers[0].poses = [ground(0.0).into(), ground(0.0).into()];
        let e = scene.validate().unwrap_err().to_string();
        assert!(
            e.contains("layer 0 pose in frame 1") && e.contains("polygon"),
            "{e}"
        );
        scene.layers[0].shape = Shape::Polygon {
            vertices: vec![(-4.0, 1.0), (4.0, 1.0), (4.0, 12.0), (-4.0, 12.0)],
        };
        scene.layers[0].poses[1] = ground(2.0).into();
        let e = scene.validate().unwrap_err().to_string();
        assert!(
            e.contains("frame 2") && e.contains("beyond the horizon"),
            "{e}"
        );
    }
}
