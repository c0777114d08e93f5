//! Upright boxes standing on the ground of `scene::ground` (parked cars, vans, posts, walls),
//! still in the world: each face moves as the camera's motion at its own depth dictates, so
//! the boxes bring the parallax and occlusion edges of a roadside, with a face's flow exact
//! through its plane's homography ([`Ground::plane_poses`]).
//!
//! World coordinates are metres: X to the right, Y up from the ground, Z ahead.

use super::ground::{Ground, HEIGHT};

/// A box standing on the ground: X from `x[0]` to `x[1]`, Z from `z[0]` to `z[1]`, `height`
/// tall.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Block {
    pub x: [f64; 2],
    pub z: [f64; 2],
    pub height: f64,
}

/// A rectangular face: its centre, its unit axes (`e_v` points down the image) and its half
/// extents along them, metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Face {
    pub centre: [f64; 3],
    pub e_u: [f64; 3],
    pub e_v: [f64; 3],
    pub half: [f64; 2],
}

impl Face {
    /// The corners, as (u, v) multiples of the unit axes.
    pub fn corners(&self) -> [(f64, f64); 4] {
        let [a, b] = self.half;
        [(-a, -b), (a, -b), (a, b), (-a, b)]
    }
}

impl Block {
    /// Whether the footprints of two boxes overlap, with `gap` metres kept between them.
    pub fn overlaps(&self, other: &Block, gap: f64) -> bool {
        self.x[0] < other.x[1] + gap
            && other.x[0] < self.x[1] + gap
            && self.z[0] < other.z[1] + gap
            && other.z[0] < self.z[1] + gap
    }

    /// The faces a camera at either of `ground`'s two positions sees, in painting order: the
    /// sides, the top, then the front (toward the camera, seen from both positions as long as
    /// both lie before `z[0]`). A side turned away in one frame is drawn first, so the faces
    /// that frame does see cover it: the silhouette of a box is the union of the faces turned
    /// toward the camera. This holds while the camera does not pass the box's whole width
    /// between the frames (a slide narrower than the box).
    pub fn faces(&self, ground: &Ground) -> Vec<Face> {
        let [x0, x1] = self.x;
        let [z0, z1] = self.z;
        let h = self.height;
        let (xc, zc) = (0.5 * (x0 + x1), 0.5 * (z0 + z1));
        let (hx, hz) = (0.5 * (x1 - x0), 0.5 * (z1 - z0));
        let cams = ground.positions().map(|(x, _)| x);
        let down = [0.0, -1.0, 0.0];
        let mut faces = Vec::with_capacity(3);
        if cams.iter().any(|&c| c < x0) {
            faces.push(Face {
                centre: [x0, 0.5 * h, zc],
                e_u: [0.0, 0.0, -1.0],
                e_v: down,
                half: [hz, 0.5 * h],
            });
        }
        if cams.iter().any(|&c| c > x1) {
            faces.push(Face {
                centre: [x1, 0.5 * h, zc],
                e_u: [0.0, 0.0, 1.0],
                e_v: down,
                half: [hz, 0.5 * h],
            });
        }
        if h < HEIGHT {
            faces.push(Face {
                centre: [xc, h, zc],
                e_u: [1.0, 0.0, 0.0],
                e_v: [0.0, 0.0, -1.0],
                half: [hx, hz],
            });
        }
        faces.push(Face {
            centre: [xc, 0.5 * h, z0],
            e_u: [1.0, 0.0, 0.0],
            e_v: down,
            half: [hx, 0.5 * h],
        });
        faces
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ground(slide: f64) -> Ground {
        Ground {
            f: 300.0,
            cx: 256.0,
            horizon: 150.0,
            height: 384.0,
            advance: 0.3,
            slide,
            turn: 0.0,
        }
    }

    /// A box to the right shows its left side, one to the left its right side, one ahead
    /// neither; a box lower than the camera shows its top; the front comes last.
    #[test]
    fn each_box_shows_the_faces_turned_toward_the_camera() {
        let g = ground(0.0);
        let right = Block {
            x: [2.0, 3.8],
            z: [8.0, 12.0],
            height: 1.4,
        };
        let f = right.faces(&g);
        assert_eq!(f.len(), 3);
        assert_eq!(f[0].centre, [2.0, 0.7, 10.0]);
        assert_eq!(f[1].centre, [2.9, 1.4, 10.0], "the top");
        assert_eq!(f[2].centre, [2.9, 0.7, 8.0], "the front");
        let left = Block {
            x: [-3.8, -2.0],
            height: 3.0,
            ..right
        };
        let f = left.faces(&g);
        assert_eq!(f.len(), 2, "a van taller than the camera: no top");
        assert_eq!(f[0].centre[0], -2.0);
        let ahead = Block {
            x: [-0.9, 0.9],
            ..right
        };
        assert_eq!(ahead.faces(&g).len(), 2);
        // A slide past a side's plane shows that side in the frame it reaches.
        let ahead_right = Block {
            x: [-0.05, 1.9],
            ..right
        };
        assert_eq!(ahead_right.faces(&ground(0.0)).len(), 2);
        assert_eq!(ahead_right.faces(&ground(-0.08)).len(), 3);
    }

    /// Each face's corners lie on the box: a side at its X, the top at its height, the front
    /// at its near Z, every corner within the box's extent.
    #[test]
    fn the_faces_lie_on_the_box() {
        let b = Block {
            x: [1.0, 2.5],
            z: [6.0, 10.0],
            height: 1.2,
        };
        for face in b.faces(&ground(0.0)) {
            for (u, v) in face.corners() {
                let p: Vec<f64> = (0..3)
                    .map(|i| face.centre[i] + u * face.e_u[i] + v * face.e_v[i])
                    .collect();
                assert!(p[0] >= 1.0 - 1e-12 && p[0] <= 2.5 + 1e-12, "{p:?}");
                assert!(p[1] >= -1e-12 && p[1] <= 1.2 + 1e-12, "{p:?}");
                assert!(p[2] >= 6.0 - 1e-12 && p[2] <= 10.0 + 1e-12, "{p:?}");
            }
        }
        let a = Block {
            x: [0.0, 1.0],
            z: [5.0, 6.0],
            height: 1.0,
        };
        let near = Block { x: [1.2, 2.0], ..a };
        assert!(a.overlaps(&near, 0.3) && !a.overlaps(&near, 0.1));
    }
}
