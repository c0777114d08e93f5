//! Flow visualisation with the Middlebury colour wheel (Baker et al. 2011): hue is direction,
//! saturation is magnitude relative to the largest flow shown.

use crate::types::{Flow, Image};

/// The 55 colours of the wheel: red → yellow → green → cyan → blue → magenta → red, with the
/// segment lengths of the original code (15, 6, 4, 11, 13, 6) chosen for perceptual spacing.
fn colour_wheel() -> Vec<[f32; 3]> {
    let segments: [(usize, [f32; 3], [f32; 3]); 6] = [
        (15, [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]),
        (6, [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]),
        (4, [0.0, 1.0, 0.0], [0.0, 1.0, 1.0]),
        (11, [0.0, 1.0, 1.0], [0.0, 0.0, 1.0]),
        (13, [0.0, 0.0, 1.0], [1.0, 0.0, 1.0]),
        (6, [1.0, 0.0, 1.0], [1.0, 0.0, 0.0]),
    ];
    let mut wheel = Vec::with_capacity(55);
    for (n, a, b) in segments {
        for i in 0..n {
            let t = i as f32 / n as f32;
            wheel.push([
                a[0] + (b[0] - a[0]) * t,
                a[1] + (b[1] - a[1]) * t,
                a[2] + (b[2] - a[2]) * t,
            ]);
        }
    }
    wheel
}

/// Colour of one vector already divided by the normalising radius.
fn vector_colour(wheel: &[[f32; 3]], u: f32, v: f32) -> [f32; 3] {
    if !(u.is_finite() && v.is_finite()) {
        return [0.0, 0.0, 0.0];
    }
    let n = wheel.len();
    let rad = (u * u + v * v).sqrt();
    let a = (-v).atan2(-u) / std::f32::consts::PI; // in [−1, 1]
    let fk = (a + 1.0) / 2.0 * (n - 1) as f32;
    let k0 = (fk.floor() as usize).min(n - 1);
    let k1 = (k0 + 1) % n;
    let f = fk - k0 as f32;
    let mut rgb = [0.0; 3];
    for c in 0..3 {
        let col = (1.0 - f) * wheel[k0][c] + f * wheel[k1][c];
        rgb[c] = if rad <= 1.0 {
            1.0 - rad * (1.0 - col)
        } else {
            col * 0.75
        };
    }
    rgb
}

/// An RGB image of `flow`: white at rest, saturated colours at `max_radius` (or, when `None`,
/// at the largest finite magnitude in the field). Unknown vectors are black.
pub fn flow_to_image(flow: &Flow, max_radius: Option<f32>) -> Image {
    let wheel = colour_wheel();
    let r = max_radius.unwrap_or_else(|| flow.max_magnitude()).max(1e-6);
    let (h, w) = (flow.height(), flow.width());
    let mut img = Image::zeros(3, h, w);
    for y in 0..h {
        for x in 0..w {
            let (u, v) = flow.get(y, x);
            let rgb = vector_colour(&wheel, u / r, v / r);
            for (c, val) in rgb.iter().enumerate() {
                img.set(c, y, x, *val);
            }
        }
    }
    img
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wheel_directions_follow_middlebury() {
        let wheel = colour_wheel();
        assert_eq!(wheel.len(), 55);
        // Zero flow is white; motion to the right (+u) is red-ish; up (−v) is yellow-green.
        assert_eq!(vector_colour(&wheel, 0.0, 0.0), [1.0, 1.0, 1.0]);
        let right = vector_colour(&wheel, 1.0, 0.0);
        assert!(right[0] > 0.9 && right[2] < 0.1, "{right:?}");
        let left = vector_colour(&wheel, -1.0, 0.0);
        assert!(left[2] > 0.5 && left[0] < 0.2, "{left:?}");
        assert_eq!(vector_colour(&wheel, f32::NAN, 0.0), [0.0, 0.0, 0.0]);
        let mut f = Flow::zeros(2, 2);
        f.set(0, 0, 3.0, 4.0);
        let img = flow_to_image(&f, None);
        assert!(img.data().iter().all(|v| (0.0..=1.0).contains(v)));
    }
}
