//! The chairs scenes' tests: determinism, motion, the options of real cameras (photos, laws,
//! still and plain backgrounds, small and flat sprites, tone, the ground plane), validation.

use super::*;
use std::path::Path;

fn small() -> ChairsConfig {
    ChairsConfig {
        width: 64,
        height: 48,
        supersample: 2,
        ..ChairsConfig::default()
    }
}

#[test]
fn scenes_are_deterministic_and_move() {
    let cfg = small();
    let a = cfg.build(5).unwrap();
    let b = cfg.build(5).unwrap();
    assert_eq!(a.render(0).unwrap(), b.render(0).unwrap());
    assert_eq!(a.flow().unwrap(), b.flow().unwrap());
    assert_ne!(
        a.render(0).unwrap(),
        cfg.build(6).unwrap().render(0).unwrap()
    );
    assert!(!a.is_static());
    let f = a.flow().unwrap();
    assert!(f.max_magnitude() > 0.0 && f.max_magnitude() < 80.0);
}

#[test]
fn warping_frame2_by_the_flow_reproduces_frame1() {
    // Brightness constancy on non-occluded pixels: the exactness of the flow.
    let cfg = ChairsConfig {
        supersample: 1,
        sprites: [2, 2],
        ..small()
    };
    let scene = cfg.build(3).unwrap();
    let (f1, f2, flow) = (
        scene.render(0).unwrap(),
        scene.render(1).unwrap(),
        scene.flow().unwrap(),
    );
    let (mut err_flow, mut err_zero, mut n) = (0.0f64, 0.0f64, 0);
    for y in 4..44 {
        for x in 4..60 {
            let (u, v) = flow.get(y, x);
            let (x2, y2) = (x as f32 + u, y as f32 + v);
            if x2 < 0.0 || y2 < 0.0 || x2 > 63.0 || y2 > 47.0 {
                continue;
            }
            let warped = super::super::texture::sample_bilinear(&f2, 1, x2, y2);
            err_flow += (warped - f1.get(1, y, x)).abs() as f64;
            err_zero += (f2.get(1, y, x) - f1.get(1, y, x)).abs() as f64;
            n += 1;
        }
    }
    assert!(n > 1000);
    assert!(
        err_flow < 0.5 * err_zero,
        "warp {err_flow} vs zero-flow {err_zero}"
    );
}

#[test]
fn a_still_camera_and_still_sprites_make_a_static_scene() {
    let cfg = ChairsConfig {
        still_background: 1.0,
        still_sprites: 1.0,
        ..small()
    };
    let (scene, draw) = cfg.build_recorded(4).unwrap();
    assert!(draw.still_background);
    assert!(scene.is_static());
    // A still background alone: the flow is exactly zero wherever the background shows.
    let cfg = ChairsConfig {
        still_background: 1.0,
        sprites: [1, 1],
        sprite_radius: [0.1, 0.1],
        ..small()
    };
    let flow = cfg.build(4).unwrap().flow().unwrap();
    let zero = (0..48)
        .flat_map(|y| (0..64).map(move |x| (y, x)))
        .filter(|&(y, x)| flow.get(y, x) == (0.0, 0.0))
        .count();
    assert!(zero > 64 * 48 / 2, "{zero} still pixels");
    assert!(flow.max_magnitude() > 0.0);
}

#[test]
fn the_log_uniform_law_spans_sub_pixel_to_large_motions() {
    let cfg = ChairsConfig {
        translation_law: TranslationLaw::LogUniform,
        min_translation: 0.1,
        max_translation: 128.0,
        ..small()
    };
    let mut r = rng::stream(1, &[9]);
    let lens: Vec<f64> = (0..4000)
        .map(|_| {
            let (x, y) = cfg.translation(&mut r, 128.0);
            x.hypot(y)
        })
        .collect();
    assert!(
        lens.iter()
            .all(|&l| (0.1 - 1e-9..=128.0 + 1e-9).contains(&l))
    );
    // Log-uniform: each of the ten octaves holds about a tenth of the draws.
    let below_1 = lens.iter().filter(|&&l| l < 1.0).count() as f64 / 4000.0;
    let above_32 = lens.iter().filter(|&&l| l > 32.0).count() as f64 / 4000.0;
    let octave = 1.0 / (1280.0f64).log2();
    assert!((below_1 - 10f64.log2() * octave).abs() < 0.04, "{below_1}");
    assert!((above_32 - 2.0 * octave).abs() < 0.04, "{above_32}");
}

#[test]
fn knobs_are_drawn_apart_from_the_geometry() {
    // Tone and still sprites change what is drawn, not where: the first frame's layer
    // geometry is that of the plain config.
    let plain = small();
    let knobs = ChairsConfig {
        still_sprites: 0.5,
        brightness: [0.3, 0.6],
        contrast: [0.5, 0.9],
        ..small()
    };
    assert!(!plain.has_variety() && knobs.has_variety());
    let (a, b) = (plain.build(8).unwrap(), knobs.build(8).unwrap());
    let (ra, rb) = (a.records(), b.records());
    assert_eq!(ra.len(), rb.len());
    for (x, y) in ra.iter().zip(&rb) {
        assert_eq!(x.poses[0], y.poses[0]);
    }
    // Darker and flatter, within [0, 1].
    let (ia, ib) = (a.render(0).unwrap(), b.render(0).unwrap());
    let mean = |d: &[f32]| d.iter().map(|&v| v as f64).sum::<f64>() / d.len() as f64;
    assert!(mean(ib.data()) < 0.75 * mean(ia.data()));
    assert!(ib.data().iter().all(|v| (0.0..=1.0).contains(v)));
}

#[test]
fn small_sprites_and_photo_textures_are_recorded() {
    let photos = Path::new(env!("CARGO_MANIFEST_DIR")).join("datasets/photos/train");
    let cfg = ChairsConfig {
        sprites: [1, 1],
        small_sprites: [3, 3],
        small_sprite_radius_px: [3.0, 3.0],
        photos: Some(PhotoTextures {
            dirs: vec![photos],
            fraction: 1.0,
            ..PhotoTextures::default()
        }),
        ..small()
    };
    let (scene, draw) = cfg.build_recorded(2).unwrap();
    assert_eq!(scene.layers.len(), 1 + 1 + 3);
    assert_eq!(draw.textures.len(), 5);
    assert!(draw.textures.iter().all(|t| t.is_some()));
    for layer in &scene.layers[2..] {
        assert!(matches!(layer.shape, Shape::Blob { radius, .. } if radius == 3.0));
    }
    assert_eq!(cfg.build_recorded(2).unwrap().1, draw);
    let half = ChairsConfig {
        photos: Some(PhotoTextures {
            fraction: 0.5,
            ..cfg.photos.clone().unwrap()
        }),
        small_sprites: [20, 20],
        ..cfg.clone()
    };
    let textures = half.build_recorded(3).unwrap().1.textures;
    let photo = textures.iter().filter(|t| t.is_some()).count();
    assert!(
        photo > 3 && photo < textures.len() - 3,
        "{photo} of {}",
        textures.len()
    );
}

/// Flat sprites: every sprite's texture is one colour, some are long, each mark lies inside
/// its sprite in frame 1 and moves exactly as the sprite's own point beneath it (so the flow,
/// which each layer's poses make exact, is the sprite's there); the large sprites' poses are
/// those the same seed draws without the knob.
#[test]
fn flat_sprites_are_one_colour_and_their_marks_ride_on_them() {
    let base = ChairsConfig {
        width: 160,
        height: 120,
        sprites: [3, 3],
        sprite_radius: [0.15, 0.25],
        small_sprites: [2, 2],
        small_sprite_radius_px: [6.0, 10.0],
        still_background: 1.0,
        ..ChairsConfig::default()
    };
    let flat = ChairsConfig {
        flat_sprites: 1.0,
        ..base.clone()
    };
    assert!(flat.has_variety());
    let (mut marks, mut longest) = (0, 0.0f64);
    for seed in 0..12 {
        let scene = flat.build(seed).unwrap();
        // The large sprites' geometry is the plain config's (their stream is not touched).
        let blobs = |s: &LayeredScene| -> Vec<_> {
            s.records()
                .into_iter()
                .filter(|r| matches!(r.shape, Shape::Blob { .. } | Shape::Polygon { .. }))
                .take(3)
                .map(|r| r.poses)
                .collect()
        };
        assert_eq!(blobs(&base.build(seed).unwrap()), blobs(&scene));
        let mut sprite: Option<usize> = None;
        for (i, layer) in scene.layers.iter().enumerate().skip(1) {
            let Fill::Texture { image, .. } = &layer.fill else {
                panic!("seed {seed}: layer {i} is not a texture");
            };
            for c in 0..3 {
                let plane = image.plane(c);
                assert!(
                    plane.iter().all(|&v| v == plane[0]),
                    "seed {seed}: layer {i}"
                );
            }
            match &layer.shape {
                Shape::Polygon { vertices } => {
                    let extent = |f: fn(&(f64, f64)) -> f64| {
                        let v = vertices.iter().map(f);
                        v.clone().fold(f64::MIN, f64::max) - v.fold(f64::MAX, f64::min)
                    };
                    longest = longest.max(extent(|p| p.0) / extent(|p| p.1));
                    sprite = Some(i);
                }
                Shape::Disc { radius: mark } => {
                    marks += 1;
                    let s = sprite.expect("a mark follows its sprite");
                    let body = &scene.layers[s];
                    for k in 0..16 {
                        let a = k as f64 * std::f64::consts::PI / 8.0;
                        let (lx, ly) = (mark * a.cos(), mark * a.sin());
                        let p1 = layer.poses[0].apply(lx, ly).unwrap();
                        let q = body.poses[0].inverse().unwrap().apply(p1.0, p1.1).unwrap();
                        assert!(body.shape.contains(q.0, q.1), "seed {seed}: mark outside");
                        let moved = body.poses[1].apply(q.0, q.1).unwrap();
                        let p2 = layer.poses[1].apply(lx, ly).unwrap();
                        assert!((moved.0 - p2.0).hypot(moved.1 - p2.1) < 1e-9);
                    }
                }
                other => panic!("seed {seed}: unexpected shape {other:?}"),
            }
        }
    }
    assert!(marks >= 12, "{marks} marks in 12 scenes of 5 sprites");
    // Stretched up to 4:1 along their local x (the blob's own outline varies too).
    assert!(longest > 2.5 && longest < 6.0, "longest {longest}");
}

#[test]
fn bad_config_is_rejected() {
    assert!(
        ChairsConfig {
            sprites: [5, 2],
            ..small()
        }
        .validate()
        .is_err()
    );
    assert!(
        ChairsConfig {
            max_translation: f64::NAN,
            ..small()
        }
        .validate()
        .is_err()
    );
    assert!(
        ChairsConfig {
            width: 0,
            ..small()
        }
        .validate()
        .is_err()
    );
    assert!(
        ChairsConfig {
            flat_sprites: 1.5,
            ..small()
        }
        .validate()
        .is_err()
    );
    assert!(serde_json::from_str::<ChairsConfig>(r#"{"sprite": [1, 2]}"#).is_err());
}

/// Every seed below `seeds` builds a scene (none is refused, e.g. as beyond the horizon).
fn every_seed_draws(cfg: &ChairsConfig, seeds: u64) {
    for seed in 0..seeds {
        if let Err(e) = cfg.build(seed) {
            panic!("seed {seed}: {e}");
        }
    }
}

/// Brightness constancy of a 160×120 colour scene over `rows` × `cols`: the mean absolute
/// difference between frame 1 and frame 2 sampled at x + flow, the same in place, and the
/// samples counted (pixels whose x + flow stays inside the frame, times channels).
fn constancy(
    scene: &LayeredScene,
    rows: std::ops::Range<usize>,
    cols: std::ops::Range<usize>,
) -> (f64, f64, usize) {
    let flow = scene.flow().unwrap();
    let (f1, f2) = (scene.render(0).unwrap(), scene.render(1).unwrap());
    let (mut moved, mut still, mut n) = (0.0, 0.0, 0);
    for y in rows {
        for x in cols.clone() {
            let (u, v) = flow.get(y, x);
            let (x2, y2) = (x as f32 + u, y as f32 + v);
            if !(0.0..158.0).contains(&x2) || !(0.0..118.0).contains(&y2) {
                continue;
            }
            for c in 0..3 {
                let a = f1.get(c, y, x);
                moved += (super::super::texture::sample_bilinear(&f2, c, x2, y2) - a).abs() as f64;
                still += (f2.get(c, y, x) - a).abs() as f64;
                n += 1;
            }
        }
    }
    let n_f = n.max(1) as f64;
    (moved / n_f, still / n_f, n)
}

/// A ground plane under a camera driving ahead: below the patch's far edge the flow points
/// down and grows row by row to the bottom, where it is (H − horizon)·a/(1 − a) at most;
/// frame 2 at x + flow shows what frame 1 shows at x; the far world above does not move;
/// the same seed without the ground draws the same layers otherwise.
#[test]
fn a_ground_plane_flows_down_and_out_and_its_frames_agree() {
    let still_world = ChairsConfig {
        width: 160,
        height: 120,
        supersample: 2,
        sprites: [0, 0],
        background_translation: 0.0,
        background_rotation_deg: 0.0,
        background_zoom: [1.0, 1.0],
        ..ChairsConfig::default()
    };
    let cfg = ChairsConfig {
        ground: 1.0,
        ground_advance: [0.2, 0.3],
        ..still_world.clone()
    };
    for seed in [3u64, 4, 5] {
        let scene = cfg.build(seed).unwrap();
        assert_eq!(scene.layers.len(), 2, "background and ground");
        let flow = scene.flow().unwrap();
        // The mean downward flow of each row.
        let row_v: Vec<f64> = (0..120)
            .map(|y| (0..160).map(|x| flow.get(y, x).1 as f64).sum::<f64>() / 160.0)
            .collect();
        assert!(
            row_v[..30].iter().all(|v| v.abs() < 1e-9),
            "{:?}",
            &row_v[..30]
        );
        let bottom = row_v[119];
        assert!(
            bottom > 5.0 && bottom <= 0.7 * 120.0 * 0.3 / 0.7 + 1.0,
            "{bottom}"
        );
        for y in 100..119 {
            assert!(
                row_v[y] < row_v[y + 1],
                "row {y}: {} then {}",
                row_v[y],
                row_v[y + 1]
            );
        }
        // Brightness constancy where the ground stays in the frame.
        let (moved, still, n) = constancy(&scene, 70..110, 30..130);
        assert!(n > 3000, "{n}");
        assert!(
            moved < 0.3 * still,
            "seed {seed}: {moved} along the flow, {still} in place"
        );
        // Without the ground: the same background.
        let plain = still_world.build(seed).unwrap();
        assert_eq!(plain.records()[0], scene.records()[0]);
    }
    // The largest advance with the widest turns and views: every scene is drawn.
    let fast = ChairsConfig {
        ground_advance: [0.8, 0.8],
        sprites: [0, 0],
        ..cfg.clone()
    };
    every_seed_draws(&fast, 64);
    let bad = ChairsConfig {
        ground_advance: [0.2, 0.9],
        ..cfg
    };
    assert!(
        bad.validate()
            .unwrap_err()
            .to_string()
            .contains("scene.ground_advance")
    );
}

/// Boxes standing on the road: each sample draws the same background and ground as without
/// them, then one to four faces per box; frame 2 at x + flow shows what frame 1 shows at x
/// (on average, over the pixels the boxes hide in one frame too); the largest advance with the
/// most boxes draws every scene; the count is validated.
#[test]
fn boxes_on_the_road_keep_the_road_and_their_frames_agree() {
    let road = ChairsConfig {
        width: 160,
        height: 120,
        supersample: 2,
        sprites: [0, 0],
        background_translation: 0.0,
        background_rotation_deg: 0.0,
        background_zoom: [1.0, 1.0],
        ground: 1.0,
        ground_advance: [0.2, 0.3],
        ..ChairsConfig::default()
    };
    let cfg = ChairsConfig {
        ground_objects: [3, 6],
        ..road.clone()
    };
    let mut faces = 0;
    for seed in [3u64, 4, 5, 6] {
        let scene = cfg.build(seed).unwrap();
        let plain = road.build(seed).unwrap();
        assert_eq!(plain.layers.len(), 2);
        assert_eq!(scene.records()[..2], plain.records()[..]);
        faces += scene.layers.len() - 2;
        // Brightness constancy below the horizon's band, where the boxes and the road are.
        let (moved, still, n) = constancy(&scene, 40..118, 2..158);
        assert!(n > 3 * 5000, "{n}");
        assert!(
            moved < 0.25 * still,
            "seed {seed}: {moved} along the flow, {still} in place"
        );
    }
    assert!(faces >= 4 * 3, "{faces} faces in 4 scenes");
    let crowded = ChairsConfig {
        ground_advance: [0.8, 0.8],
        ground_objects: [32, 32],
        ..cfg.clone()
    };
    every_seed_draws(&crowded, 32);
    for bad in [[4, 3], [0, 33]] {
        let err = ChairsConfig {
            ground_objects: bad,
            ..cfg.clone()
        }
        .validate()
        .unwrap_err()
        .to_string();
        assert!(err.contains("scene.ground_objects"), "{err}");
    }
}
