//! Test patterns: the rocket and small discs of Note S12 (Fig. S10, 701×701 frames) and dot-grid
//! calibration targets (Note S3).

use serde::{Deserialize, Serialize};

use super::affine::Affine;
use super::layered::{Fill, Layer, LayeredScene};
use super::pose::Pose;
use super::shape::Shape;
use crate::error::{Error, Result};
use crate::types::Image;

/// Frame size of the Note S12 tests.
pub const S12_SIZE: usize = 701;

/// Frame sides the test patterns may be drawn in: from the smallest that holds the rocket and
/// its step (its outline spans 190 × 90 px) to the largest a detection-limit sweep needs.
pub const SIDES: std::ops::RangeInclusive<usize> = 200..=4096;

fn check_side(side: usize) -> Result<()> {
    if SIDES.contains(&side) {
        return Ok(());
    }
    Err(Error::invalid(
        "frame side",
        format!(
            "must be {} to {} px, got {side}",
            SIDES.start(),
            SIDES.end()
        ),
    ))
}

/// Direction of the rocket's 3-pixel step (Fig. S10a–c).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RocketStep {
    Up,
    Left,
    UpRight,
}

impl RocketStep {
    /// The displacement in pixels (x right, y down).
    pub fn displacement(self) -> (f64, f64) {
        match self {
            RocketStep::Up => (0.0, -3.0),
            RocketStep::Left => (-3.0, 0.0),
            RocketStep::UpRight => (3.0, -3.0),
        }
    }
}

/// Rocket outline in local pixels, nose up, about 180 px tall: nose cone, body, two fins.
fn rocket_outline() -> Vec<(f64, f64)> {
    vec![
        (0.0, -95.0),
        (14.0, -70.0),
        (20.0, -45.0),
        (20.0, 40.0),
        (45.0, 75.0),
        (45.0, 90.0),
        (20.0, 70.0),
        (12.0, 85.0),
        (-12.0, 85.0),
        (-20.0, 70.0),
        (-45.0, 90.0),
        (-45.0, 75.0),
        (-20.0, 40.0),
        (-20.0, -45.0),
        (-14.0, -70.0),
    ]
}

fn dark_background(channels: usize) -> Layer {
    Layer {
        shape: Shape::Full,
        fill: Fill::Flat(vec![0.05; channels]),
        poses: [Pose::IDENTITY; 2],
    }
}

/// The rocket of Fig. S10a–c: a bright rocket with a darker window on a dark background,
/// centred in a `side × side` frame (Note S12's is [`S12_SIZE`]), moved by 3 px in `step`'s
/// direction.
pub fn rocket(step: RocketStep, channels: usize, side: usize) -> Result<LayeredScene> {
    check_side(side)?;
    let (dx, dy) = step.displacement();
    let c = side as f64 / 2.0;
    let poses = [
        Affine::translation(c, c),
        Affine::translation(c + dx, c + dy),
    ];
    let body = Layer {
        shape: Shape::Polygon {
            vertices: rocket_outline(),
        },
        fill: Fill::Flat(vec![0.9; channels]),
        poses: poses.map(Pose::from),
    };
    let window = Layer {
        shape: Shape::Disc { radius: 9.0 },
        fill: Fill::Flat(vec![0.35; channels]),
        poses: [
            poses[0].compose(&Affine::translation(0.0, -30.0)).into(),
            poses[1].compose(&Affine::translation(0.0, -30.0)).into(),
        ],
    };
    Ok(LayeredScene {
        width: side,
        height: side,
        channels,
        layers: vec![dark_background(channels), body, window],
        supersample: 4,
    })
}

/// A bright disc of `radius` px moving 15 px right (Fig. S10e–g), centred in a `side × side`
/// frame (Note S12's is [`S12_SIZE`]).
pub fn disc(radius: f64, channels: usize, side: usize) -> Result<LayeredScene> {
    check_side(side)?;
    // Both of its positions, 7.5 px either side of the centre, inside the frame.
    let largest = side as f64 / 2.0 - 8.0;
    if !(radius.is_finite() && radius > 0.0 && radius < largest) {
        return Err(Error::invalid(
            "disc radius",
            format!("must be in (0, {largest}) in a {side}-px frame, got {radius}"),
        ));
    }
    let c = side as f64 / 2.0;
    let layer = Layer {
        shape: Shape::Disc { radius },
        fill: Fill::Flat(vec![0.9; channels]),
        poses: [
            Affine::translation(c - 7.5, c).into(),
            Affine::translation(c + 7.5, c).into(),
        ],
    };
    Ok(LayeredScene {
        width: side,
        height: side,
        channels,
        layers: vec![dark_background(channels), layer],
        supersample: 4,
    })
}

/// A dot-grid calibration target: black dots of `radius` px on white, on a square lattice of
/// `pitch` px centred in a `width × height` frame, anti-aliased (4×4 sub-samples).
pub fn dot_grid(width: usize, height: usize, pitch: f64, radius: f64) -> Result<Image> {
    if !(pitch.is_finite() && radius.is_finite() && radius > 0.0 && pitch > 2.0 * radius) {
        return Err(Error::invalid(
            "dot grid",
            format!("need pitch > 2·radius > 0, got pitch {pitch}, radius {radius}"),
        ));
    }
    let mut img = Image::filled(1, height, width, 1.0);
    let (cx, cy) = (width as f64 / 2.0, height as f64 / 2.0);
    for y in 0..height {
        for x in 0..width {
            let mut covered = 0;
            for sy in 0..4 {
                for sx in 0..4 {
                    let px = x as f64 + (sx as f64 + 0.5) / 4.0 - 0.5 - cx;
                    let py = y as f64 + (sy as f64 + 0.5) / 4.0 - 0.5 - cy;
                    let (gx, gy) = (
                        px - (px / pitch).round() * pitch,
                        py - (py / pitch).round() * pitch,
                    );
                    if gx * gx + gy * gy <= radius * radius {
                        covered += 1;
                    }
                }
            }
            img.set(0, y, x, 1.0 - covered as f32 / 16.0);
        }
    }
    Ok(img)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rocket_steps_have_exact_flow() {
        for step in [RocketStep::Up, RocketStep::Left, RocketStep::UpRight] {
            let scene = rocket(step, 1, S12_SIZE).unwrap();
            let flow = scene.flow().unwrap();
            let (dx, dy) = step.displacement();
            assert_eq!(flow.get(350, 350), (dx as f32, dy as f32));
            assert_eq!(flow.get(5, 5), (0.0, 0.0));
        }
    }

    #[test]
    fn the_rocket_is_the_same_in_every_frame_size() {
        // Centred in each frame, the same pixels move: a larger frame only adds background.
        let moving = |side: usize| {
            let flow = rocket(RocketStep::Left, 1, side).unwrap().flow().unwrap();
            let off = side / 2 - 100;
            let mut cells = Vec::new();
            for y in 0..200 {
                for x in 0..200 {
                    cells.push(flow.get(y + off, x + off) != (0.0, 0.0));
                }
            }
            (cells, flow.u().iter().filter(|&&u| u != 0.0).count())
        };
        let (small, n_small) = moving(201);
        for side in [401, S12_SIZE, 1201] {
            let (big, n_big) = moving(side);
            assert_eq!(n_big, n_small, "{side}: every moving pixel is the rocket's");
            assert!(
                small == big,
                "{side}: the rocket is drawn as in a 201-px frame"
            );
        }
        assert!(n_small > 5000, "{n_small}");
        assert!(rocket(RocketStep::Up, 1, 150).is_err());
        assert!(rocket(RocketStep::Up, 1, 5000).is_err());
    }

    #[test]
    fn discs_move_fifteen_pixels_right() {
        let scene = disc(3.0, 1, S12_SIZE).unwrap();
        let flow = scene.flow().unwrap();
        assert_eq!(flow.get(350, 343), (15.0, 0.0));
        let moving = flow.u().iter().filter(|&&u| u != 0.0).count();
        assert!(
            (20..=40).contains(&moving),
            "{moving} px for a radius-3 disc"
        );
        assert!(disc(0.0, 1, S12_SIZE).is_err());
        assert!(
            disc(95.0, 1, 200).is_err(),
            "its second position leaves the frame"
        );
        assert!(disc(90.0, 1, 200).is_ok());
    }

    #[test]
    fn dot_grid_has_dots_at_lattice_points() {
        let g = dot_grid(100, 80, 20.0, 4.0).unwrap();
        assert_eq!(g.get(0, 40, 50), 0.0);
        assert_eq!(g.get(0, 50, 60), 1.0);
        assert!(dot_grid(10, 10, 5.0, 3.0).is_err());
    }
}
