//! A chairs scene's road: the ground plane under a camera that drives ahead (`scene::ground`)
//! and the boxes standing on it (`scene::block`), every layer a plane of the world whose flow
//! is exact through its homography. The ground draws from its own random stream and the boxes
//! from another, so that configs without them keep their scenes, and a config without boxes
//! keeps its roads.

use std::sync::Arc;

use rand::RngExt;

use super::{ChairsConfig, uniform};
use crate::rng;
use crate::scene::block::Block;
use crate::scene::ground::{FAR, FAR_MIN, Ground};
use crate::scene::layered::{Fill, Layer};
use crate::scene::pose::{Homography, Pose};
use crate::scene::shape::Shape;
use crate::types::Image;

/// A texture of `(height, width)` px drawn with the given stream (photo or procedural, with the
/// scene's tone), its `seed` and feature `scale`, px; recorded as the next layer's.
pub(super) type Texture<'a> = dyn FnMut(&mut rng::Rng, bool, u64, usize, usize, f32) -> Image + 'a;

/// The largest side of a box face's texture, px.
const FACE_TEXELS: f64 = 512.0;

/// The road's layers (none when the sample draws no ground), bottom to top: the ground, then
/// the boxes from the farthest to the nearest.
pub(super) fn draw(cfg: &ChairsConfig, seed: u64, texture: &mut Texture) -> Vec<Layer> {
    let mut g = rng::stream(seed, &[rng::purpose::SCENE, rng::purpose::GROUND]);
    if !(cfg.ground > 0.0 && g.random::<f64>() < cfg.ground) {
        return Vec::new();
    }
    let (w, h) = (cfg.width as f64, cfg.height as f64);
    let short = w.min(h);
    let ground = Ground {
        f: w * g.random_range(0.5..0.8),
        cx: w * g.random_range(0.4..0.6),
        horizon: h * g.random_range(0.3..0.45),
        height: h,
        advance: uniform(&mut g, cfg.ground_advance),
        slide: g.random_range(-0.1..=0.1),
        turn: g.random_range(-1.5..=1.5f64).to_radians(),
    };
    // The patch: from just below the bottom row to FAR times as deep, a trapezoid twice as wide
    // as the view at every depth (so the slide and the turn stay inside it, and its near
    // corners stay in front of the camera in frame 2).
    let (near, far) = (0.97 * ground.near(), FAR * ground.near());
    let half_at = |z: f64| 1.2 * w / ground.f * z + 0.1;
    let half = half_at(far);
    // At most 1536 texture pixels on the patch's longer side.
    let metres = (2.0 * half).max(far - near) / 1536.0;
    let (tw, th) = ((2.0 * half / metres).ceil(), ((far - near) / metres).ceil());
    let tex_seed = g.random();
    let tex = texture(
        &mut g,
        false,
        tex_seed,
        th as usize,
        tw as usize,
        short as f32,
    );
    let z_centre = 0.5 * (near + far);
    let (u, v) = (half / metres, 0.5 * (far - near) / metres);
    let [p1, p2] = ground.poses(metres, z_centre);
    // The near edge below the bottom row; the far edge uneven, seven points each FAR_MIN..FAR
    // times the nearest depth (a skyline, not one straight boundary).
    let u_near = half_at(near) / metres;
    let mut vertices = vec![(-u_near, v), (u_near, v)];
    for k in 0..7 {
        let z = ground.near() * g.random_range(FAR_MIN..=FAR);
        vertices.push((u - 2.0 * u * k as f64 / 6.0, (z_centre - z) / metres));
    }
    let mut layers = vec![Layer {
        shape: Shape::Polygon { vertices },
        fill: Fill::Texture {
            image: Arc::new(tex),
            origin: (tw / 2.0, th / 2.0),
        },
        poses: [p1.into(), p2.into()],
    }];
    if cfg.ground_objects[1] > 0 {
        let mut o = rng::stream(
            seed,
            &[
                rng::purpose::SCENE,
                rng::purpose::GROUND,
                rng::purpose::GROUND_OBJECTS,
            ],
        );
        for block in blocks(cfg, &ground, &mut o) {
            layers.extend(faces(&ground, &block, &mut o, texture));
        }
    }
    layers
}

/// The boxes standing on the ground, farthest first: their count drawn from
/// `ground_objects`, each on the patch (its front at least the bottom row's depth away, and
/// 0.6 of it beyond where the camera advances to, at most FAR_MIN times it), anywhere across
/// the view at its depth, 0.3 to
/// 2.5 m wide, 0.3 to 8 m long and 0.3 to 3.5 m tall (posts, cars, vans, walls), no two
/// closer than 0.2 m. A box the placement cannot fit is left out.
fn blocks(cfg: &ChairsConfig, ground: &Ground, o: &mut rng::Rng) -> Vec<Block> {
    let count = o.random_range(cfg.ground_objects[0]..=cfg.ground_objects[1]);
    let near = ground.near();
    let z_min = near * (ground.advance + 0.6).max(1.0);
    let z_max = near * FAR_MIN;
    let mut placed: Vec<Block> = Vec::with_capacity(count);
    for _ in 0..count {
        for _attempt in 0..8 {
            let z0 = o.random_range(z_min..=z_max.max(z_min));
            let width = o.random_range(0.3..=2.5);
            let length = o.random_range(0.3..=8.0);
            let height = o.random_range(0.3..=3.5);
            let reach = 1.1 * 0.5 * cfg.width as f64 / ground.f * z0;
            let xc = o.random_range(-reach..=reach);
            let block = Block {
                x: [xc - 0.5 * width, xc + 0.5 * width],
                z: [z0, z0 + length],
                height,
            };
            if placed.iter().all(|b| !b.overlaps(&block, 0.2)) {
                placed.push(block);
                break;
            }
        }
    }
    placed.sort_by(|a, b| b.z[0].total_cmp(&a.z[0]));
    placed
}

/// A face's texel size (metres), poses and corners (texels about its centre).
struct Planned {
    metres: f64,
    poses: [Homography; 2],
    vertices: Vec<(f64, f64)>,
}

/// A box's faces as layers in painting order, each with its own texture at about 1.5 texels
/// per pixel where the face is nearest (at most FACE_TEXELS on a side); none when a corner
/// would lie behind either frame's camera.
fn faces(ground: &Ground, block: &Block, o: &mut rng::Rng, texture: &mut Texture) -> Vec<Layer> {
    let scaled = |e: [f64; 3], m: f64| e.map(|x| x * m);
    let faces = block.faces(ground);
    let mut planned = Vec::with_capacity(faces.len());
    for face in &faces {
        let z_nearest = block.z[0];
        let metres =
            (z_nearest / (1.5 * ground.f)).max(2.0 * face.half[0].max(face.half[1]) / FACE_TEXELS);
        let poses = ground.plane_poses(
            face.centre,
            scaled(face.e_u, metres),
            scaled(face.e_v, metres),
        );
        let vertices: Vec<(f64, f64)> = face
            .corners()
            .iter()
            .map(|&(u, v)| (u / metres, v / metres))
            .collect();
        if !poses
            .iter()
            .all(|&p| Pose::Projective(p).in_front(&vertices))
        {
            return Vec::new();
        }
        planned.push(Planned {
            metres,
            poses,
            vertices,
        });
    }
    // Textures only for boxes that are drawn: each is recorded as the next layer's.
    faces
        .iter()
        .zip(planned)
        .map(
            |(
                face,
                Planned {
                    metres,
                    poses: [p1, p2],
                    vertices,
                },
            )| {
                let (tw, th) = (
                    (2.0 * face.half[0] / metres).ceil().max(2.0),
                    (2.0 * face.half[1] / metres).ceil().max(2.0),
                );
                let tex_seed = o.random();
                let tex = texture(
                    o,
                    false,
                    tex_seed,
                    th as usize,
                    tw as usize,
                    tw.max(th) as f32,
                );
                Layer {
                    shape: Shape::Polygon { vertices },
                    fill: Fill::Texture {
                        image: Arc::new(tex),
                        origin: (tw / 2.0, th / 2.0),
                    },
                    poses: [p1.into(), p2.into()],
                }
            },
        )
        .collect()
}
