//! A ground plane under a camera that drives ahead (the road of KITTI's scenes): the plane's
//! perspective in each frame as a homography, so its flow, growing from nothing at the
//! horizon to a hundred pixels and more at the frame's bottom, is exact.
//!
//! Ground coordinates are metres, X to the right and Z ahead, on a plane `HEIGHT` below the
//! camera. A camera of focal length `f` px with its horizon at row `y_h` and its axis at column
//! `c_x` sees (X, Z) at x = c_x + f·X/Z, y = y_h + f·HEIGHT/Z. Between the frames it advances
//! `t_z`, slides `t_x` and turns by `ψ`.

use super::pose::Homography;

/// The camera's height above the ground, metres (KITTI's: 1.65 m). Only `f·HEIGHT/Z` reaches
/// the image, so the height fixes the unit of the depths and the advance, nothing else.
pub const HEIGHT: f64 = 1.65;

/// The far edge of the plane's patch, as multiples of the nearest depth the frame sees: the
/// edge lies between a quarter and two fifths of the way from the horizon to the bottom row,
/// and the far world (the layer below) shows above it.
pub const FAR: f64 = 4.0;
pub const FAR_MIN: f64 = 2.5;

/// One camera over one ground, frame 1 to frame 2.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ground {
    /// Focal length, px.
    pub f: f64,
    /// The camera axis's column and the horizon's row, px.
    pub cx: f64,
    pub horizon: f64,
    /// Frame height, px.
    pub height: f64,
    /// The advance as a share of the nearest depth seen (the bottom row's), the slide in
    /// metres and the turn in radians (positive: to the right).
    pub advance: f64,
    pub slide: f64,
    pub turn: f64,
}

impl Ground {
    /// The depth the frame's bottom row sees, metres.
    pub fn near(&self) -> f64 {
        self.f * HEIGHT / (self.height - self.horizon)
    }

    /// Projection of ground (X, Z, 1) into frame 1's image.
    fn project(&self) -> Homography {
        Homography {
            m: [
                self.f,
                self.cx,
                0.0,
                0.0,
                self.horizon,
                self.f * HEIGHT,
                0.0,
                1.0,
                0.0,
            ],
        }
    }

    /// Ground coordinates in frame 2's camera: shifted by the motion, then turned.
    fn motion(&self) -> Homography {
        let (tz, tx) = (self.advance * self.near(), self.slide);
        let (s, c) = self.turn.sin_cos();
        Homography {
            m: [
                c,
                -s,
                -c * tx + s * tz,
                s,
                c,
                -s * tx - c * tz,
                0.0,
                0.0,
                1.0,
            ],
        }
    }

    /// The poses (local → image) in frame 1 and frame 2 of a texture whose local coordinates
    /// are its pixels about its centre, `metres` a pixel, centred on depth `z_centre`: local
    /// (u, v) is ground (metres·u, z_centre − metres·v), so the texture's top is the far edge.
    pub fn poses(&self, metres: f64, z_centre: f64) -> [Homography; 2] {
        let local = Homography {
            m: [metres, 0.0, 0.0, 0.0, -metres, z_centre, 0.0, 0.0, 1.0],
        };
        let p = self.project();
        [p.compose(&local), p.compose(&self.motion()).compose(&local)]
    }

    /// The poses (local → image) in frame 1 and frame 2 of any plane of the world: local (u, v)
    /// is the point `origin + u·e_u + v·e_v`, in world metres with X to the right, Y up from the
    /// ground and Z ahead (the camera at (0, HEIGHT, 0) in frame 1). A face standing on the
    /// ground (`scene::block`) is such a plane; on the ground itself this is [`Ground::poses`].
    pub fn plane_poses(&self, origin: [f64; 3], e_u: [f64; 3], e_v: [f64; 3]) -> [Homography; 2] {
        let (tz, tx) = (self.advance * self.near(), self.slide);
        let (s, c) = self.turn.sin_cos();
        // Each frame's camera coordinates of world (X, Y, Z, 1): X_c, HEIGHT − Y_c, Z_c.
        let cameras: [[[f64; 4]; 3]; 2] = [
            [
                [1.0, 0.0, 0.0, 0.0],
                [0.0, -1.0, 0.0, HEIGHT],
                [0.0, 0.0, 1.0, 0.0],
            ],
            [
                [c, 0.0, -s, -c * tx + s * tz],
                [0.0, -1.0, 0.0, HEIGHT],
                [s, 0.0, c, -s * tx - c * tz],
            ],
        ];
        cameras.map(|cam| {
            // The camera coordinates of local (u, v, 1): 3×3, columns e_u, e_v, origin.
            let mut m = [0.0; 9];
            for (r, row) in cam.iter().enumerate() {
                for (k, col) in [e_u, e_v, origin].iter().enumerate() {
                    m[3 * r + k] = row[0] * col[0]
                        + row[1] * col[1]
                        + row[2] * col[2]
                        + if k == 2 { row[3] } else { 0.0 };
                }
            }
            // x = c_x + f·X_c/Z_c, y = horizon + f·(HEIGHT − Y_c)/Z_c.
            let intrinsics = Homography {
                m: [
                    self.f,
                    0.0,
                    self.cx,
                    0.0,
                    self.f,
                    self.horizon,
                    0.0,
                    0.0,
                    1.0,
                ],
            };
            intrinsics.compose(&Homography { m })
        })
    }

    /// The camera's position on the ground in frame 1 and frame 2, (X, Z) metres.
    pub fn positions(&self) -> [(f64, f64); 2] {
        [(0.0, 0.0), (self.slide, self.advance * self.near())]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ground() -> Ground {
        Ground {
            f: 300.0,
            cx: 256.0,
            horizon: 150.0,
            height: 384.0,
            advance: 0.3,
            slide: 0.0,
            turn: 0.0,
        }
    }

    /// Straight ahead, a point on the axis stays on it and moves down by
    /// f·HEIGHT·(1/(Z − t_z) − 1/Z); the bottom row's ground (the nearest) moves the most,
    /// and the horizon does not move.
    #[test]
    fn driving_ahead_moves_the_road_down_and_out_from_the_horizon() {
        let g = ground();
        let [p1, p2] = g.poses(0.01, 10.0);
        let near = g.near();
        let tz = 0.3 * near;
        for z in [near, 2.0 * near, 4.0 * near] {
            let v = (10.0 - z) / 0.01;
            let (x1, y1) = p1.apply(0.0, v).unwrap();
            let (x2, y2) = p2.apply(0.0, v).unwrap();
            assert!((x1 - 256.0).abs() < 1e-9 && (x2 - 256.0).abs() < 1e-9);
            assert!((y1 - (150.0 + 300.0 * HEIGHT / z)).abs() < 1e-9);
            assert!((y2 - y1 - 300.0 * HEIGHT * (1.0 / (z - tz) - 1.0 / z)).abs() < 1e-9);
        }
        // The bottom row: (H − y_h)·a/(1 − a) px.
        let (_, y1) = p1.apply(0.0, (10.0 - near) / 0.01).unwrap();
        let (_, y2) = p2.apply(0.0, (10.0 - near) / 0.01).unwrap();
        assert!((y1 - 384.0).abs() < 1e-9 && (y2 - y1 - 234.0 * 0.3 / 0.7).abs() < 1e-9);
        // A point off the axis moves outwards.
        let (x1, _) = p1.apply(100.0, (10.0 - 2.0 * near) / 0.01).unwrap();
        let (x2, _) = p2.apply(100.0, (10.0 - 2.0 * near) / 0.01).unwrap();
        assert!(x1 > 256.0 && x2 > x1);
    }

    /// On the ground plane the general plane's poses are the ground's; a face standing upright
    /// ahead of a camera driving straight grows about the horizon's centre by z/(z − t_z).
    #[test]
    fn a_plane_of_the_world_sees_what_the_ground_sees_and_fronts_grow() {
        let g = Ground {
            slide: 0.07,
            turn: 0.013,
            ..ground()
        };
        let [p1, p2] = g.poses(0.01, 10.0);
        let [q1, q2] = g.plane_poses([0.0, 0.0, 10.0], [0.01, 0.0, 0.0], [0.0, 0.0, -0.01]);
        for (u, v) in [(0.0, 0.0), (120.0, -300.0), (-400.0, 700.0)] {
            for (p, q) in [(p1, q1), (p2, q2)] {
                let (a, b) = (p.apply(u, v).unwrap(), q.apply(u, v).unwrap());
                assert!((a.0 - b.0).abs() < 1e-9 && (a.1 - b.1).abs() < 1e-9);
            }
        }
        let g = ground();
        let (z, tz) = (12.0, 0.3 * g.near());
        let [f1, f2] = g.plane_poses([1.0, 0.8, z], [0.01, 0.0, 0.0], [0.0, -0.01, 0.0]);
        for (u, v) in [(0.0, 0.0), (50.0, 60.0), (-90.0, -40.0)] {
            let (x1, y1) = f1.apply(u, v).unwrap();
            let (x2, y2) = f2.apply(u, v).unwrap();
            let k = z / (z - tz);
            assert!((x2 - 256.0 - k * (x1 - 256.0)).abs() < 1e-9);
            assert!((y2 - 150.0 - k * (y1 - 150.0)).abs() < 1e-9);
        }
        // Its foot stands on the ground: the bottom edge's row is the ground's at depth z.
        let (_, y_foot) = f1.apply(0.0, 80.0).unwrap();
        assert!((y_foot - (150.0 + 300.0 * HEIGHT / z)).abs() < 1e-9);
    }

    /// Turning right moves the whole road left, the far part by f·ψ.
    #[test]
    fn turning_right_moves_the_road_left() {
        let g = Ground {
            advance: 0.0,
            turn: 0.02,
            ..ground()
        };
        let [p1, p2] = g.poses(0.01, 10.0);
        let far = (10.0 - 100.0) / 0.01;
        let (x1, _) = p1.apply(0.0, far).unwrap();
        let (x2, _) = p2.apply(0.0, far).unwrap();
        assert!((x2 - x1 + 300.0 * 0.02f64.tan()).abs() < 0.2, "{}", x2 - x1);
    }
}
