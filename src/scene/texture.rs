//! Procedural textures for scene layers: multi-scale value noise (fBm) through a random colour
//! palette, with stripes and cell edges mixed in, so that every patch has structure at several
//! scales, sharp edges and colour, as natural images do.

use rand::RngExt;
use rayon::prelude::*;

use crate::rng;
use crate::types::Image;

/// Deterministic lattice value in [0, 1) for integer point (i, j) of a noise field.
#[inline]
fn lattice(seed: u64, i: i64, j: i64) -> f32 {
    let h = rng::splitmix(seed ^ rng::splitmix((i as u64) ^ (j as u64).rotate_right(32)));
    (h >> 40) as f32 / (1u64 << 24) as f32
}

/// Smoothly interpolated value noise at (x, y) in lattice units, in [0, 1].
#[inline]
fn value_noise(seed: u64, x: f32, y: f32) -> f32 {
    let (xf, yf) = (x.floor(), y.floor());
    let (i, j) = (xf as i64, yf as i64);
    let (tx, ty) = (x - xf, y - yf);
    // Quintic fade: continuous second derivative, no lattice-aligned creases.
    let fade = |t: f32| t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
    let (sx, sy) = (fade(tx), fade(ty));
    let a = lattice(seed, i, j);
    let b = lattice(seed, i + 1, j);
    let c = lattice(seed, i, j + 1);
    let d = lattice(seed, i + 1, j + 1);
    let top = a + (b - a) * sx;
    let bottom = c + (d - c) * sx;
    top + (bottom - top) * sy
}

/// Fractional Brownian motion: `octaves` layers of value noise, each twice as fine and
/// `persistence` times as strong as the last; result in [0, 1].
pub fn fbm(seed: u64, x: f32, y: f32, base_period: f32, octaves: u32, persistence: f32) -> f32 {
    let (mut sum, mut norm, mut amp, mut freq) = (0.0, 0.0, 1.0, 1.0 / base_period);
    for o in 0..octaves {
        sum += amp * value_noise(seed.wrapping_add(o as u64 * 0x51ED), x * freq, y * freq);
        norm += amp;
        amp *= persistence;
        freq *= 2.0;
    }
    sum / norm
}

/// Parameters of one texture, drawn from a seed.
#[derive(Clone, Debug)]
struct TextureRecipe {
    seed: u64,
    palette: [[f32; 3]; 4],
    base_period: f32,
    octaves: u32,
    persistence: f32,
    stripe_weight: f32,
    stripe_period: f32,
    stripe_angle: f32,
    cell_weight: f32,
    cell_period: f32,
    contrast: f32,
}

impl TextureRecipe {
    fn draw(seed: u64, scale: f32) -> Self {
        let mut r = rng::stream(seed, &[rng::purpose::TEXTURE]);
        let colour = |r: &mut rng::Rng| -> [f32; 3] {
            [r.random::<f32>(), r.random::<f32>(), r.random::<f32>()]
        };
        let palette = [
            colour(&mut r),
            colour(&mut r),
            colour(&mut r),
            colour(&mut r),
        ];
        Self {
            seed: r.random(),
            palette,
            base_period: scale * r.random_range(0.08..0.5),
            octaves: r.random_range(5..8),
            persistence: r.random_range(0.45..0.7),
            stripe_weight: if r.random::<f32>() < 0.35 {
                r.random_range(0.2..0.6)
            } else {
                0.0
            },
            stripe_period: r.random_range(4.0..24.0),
            stripe_angle: r.random_range(0.0..std::f32::consts::PI),
            cell_weight: if r.random::<f32>() < 0.35 {
                r.random_range(0.3..0.8)
            } else {
                0.0
            },
            cell_period: scale * r.random_range(0.04..0.15),
            contrast: r.random_range(0.6..1.0),
        }
    }

    /// Colour at texture coordinate (x, y) in pixels.
    fn colour(&self, x: f32, y: f32) -> [f32; 3] {
        let t = fbm(
            self.seed,
            x,
            y,
            self.base_period,
            self.octaves,
            self.persistence,
        );
        // Stretch the fBm (it concentrates around 0.5) over the palette.
        let mut t = ((t - 0.5) * 2.2 * self.contrast + 0.5).clamp(0.0, 1.0);
        if self.stripe_weight > 0.0 {
            let (s, c) = self.stripe_angle.sin_cos();
            let phase = (x * c + y * s) / self.stripe_period;
            let square = if phase.rem_euclid(1.0) < 0.5 {
                1.0
            } else {
                0.0
            };
            t = t * (1.0 - self.stripe_weight) + square * self.stripe_weight;
        }
        let mut shade = 1.0;
        if self.cell_weight > 0.0 {
            // Voronoi cells on a rotated jittered lattice: polygonal patches with hard edges,
            // each with its own brightness (pebbles, tiles, foliage).
            let (s, c) = self.stripe_angle.sin_cos();
            let (u, v) = (
                (x * c - y * s) / self.cell_period,
                (x * s + y * c) / self.cell_period,
            );
            let (iu, iv) = (u.floor() as i64, v.floor() as i64);
            let (mut best, mut id) = (f32::INFINITY, (0, 0));
            for dj in -1..=1 {
                for di in -1..=1 {
                    let (ci, cj) = (iu + di, iv + dj);
                    let px = ci as f32 + lattice(self.seed ^ 0xC0, ci, cj);
                    let py = cj as f32 + lattice(self.seed ^ 0xC1, ci, cj);
                    let d = (px - u).powi(2) + (py - v).powi(2);
                    if d < best {
                        best = d;
                        id = (ci, cj);
                    }
                }
            }
            shade = 1.0 - self.cell_weight * lattice(self.seed ^ 0xCE11, id.0, id.1);
        }
        let pos = t * 3.0;
        let k = (pos.floor() as usize).min(2);
        let f = pos - k as f32;
        let (a, b) = (self.palette[k], self.palette[k + 1]);
        [
            ((a[0] + (b[0] - a[0]) * f) * shade).clamp(0.0, 1.0),
            ((a[1] + (b[1] - a[1]) * f) * shade).clamp(0.0, 1.0),
            ((a[2] + (b[2] - a[2]) * f) * shade).clamp(0.0, 1.0),
        ]
    }
}

/// A texture raster `[channels, height, width]` (channels 1 or 3) drawn from `seed`; `scale`
/// sets the size of its largest structures in pixels.
pub fn procedural(seed: u64, channels: usize, height: usize, width: usize, scale: f32) -> Image {
    let recipe = TextureRecipe::draw(seed, scale.max(4.0));
    let n = height * width;
    let mut data = vec![0.0f32; channels * n];
    let rows: Vec<Vec<[f32; 3]>> = (0..height)
        .into_par_iter()
        .map(|y| {
            (0..width)
                .map(|x| recipe.colour(x as f32, y as f32))
                .collect()
        })
        .collect();
    for (y, row) in rows.iter().enumerate() {
        for (x, rgb) in row.iter().enumerate() {
            let i = y * width + x;
            if channels == 1 {
                data[i] = 0.299 * rgb[0] + 0.587 * rgb[1] + 0.114 * rgb[2];
            } else {
                for c in 0..channels.min(3) {
                    data[c * n + i] = rgb[c];
                }
            }
        }
    }
    // Lengths match by construction.
    Image::from_vec(channels, height, width, data)
        .unwrap_or_else(|_| Image::zeros(channels, height, width))
}

/// Bilinear sample of channel `c` at (x, y) in pixel units, mirrored outside the raster.
#[inline]
pub fn sample_bilinear(img: &Image, c: usize, x: f32, y: f32) -> f32 {
    Tap::at(img.width(), img.height(), x, y).sample(img.plane(c))
}

/// Adds the bilinear sample at (x, y) of each channel to `out`: `out[c]` takes channel
/// `min(c, C − 1)` (a grey texture fills every channel). The same values as
/// [`sample_bilinear`] channel by channel, with the corners found once.
#[inline]
pub fn add_bilinear(img: &Image, x: f32, y: f32, out: &mut [f32]) {
    let tap = Tap::at(img.width(), img.height(), x, y);
    let last = img.channels() - 1;
    for (c, o) in out.iter_mut().enumerate() {
        *o += tap.sample(img.plane(c.min(last)));
    }
}

/// The four corners of a bilinear sample in a raster of width `w` (indices into a plane) and
/// the weights of the right and lower ones.
struct Tap {
    i00: usize,
    i01: usize,
    i10: usize,
    i11: usize,
    tx: f32,
    ty: f32,
}

impl Tap {
    /// The corners of (x, y) in a `w × h` raster, mirrored outside it.
    #[inline]
    fn at(w: usize, h: usize, x: f32, y: f32) -> Self {
        let (xf, yf) = (x.floor(), y.floor());
        // Both neighbours inside: the mirror is the identity (the common case, without its
        // remainder).
        let pair = |f: f32, n: usize| {
            if f >= 0.0 && f + 1.0 < n as f32 {
                (f as usize, f as usize + 1)
            } else {
                let m = |i: f32| crate::imaging::convolve::mirror(i as isize, n);
                (m(f), m(f + 1.0))
            }
        };
        let ((x0, x1), (y0, y1)) = (pair(xf, w), pair(yf, h));
        Self {
            i00: y0 * w + x0,
            i01: y0 * w + x1,
            i10: y1 * w + x0,
            i11: y1 * w + x1,
            tx: x - xf,
            ty: y - yf,
        }
    }

    #[inline]
    fn sample(&self, p: &[f32]) -> f32 {
        let top = p[self.i00] * (1.0 - self.tx) + p[self.i01] * self.tx;
        let bottom = p[self.i10] * (1.0 - self.tx) + p[self.i11] * self.tx;
        top * (1.0 - self.ty) + bottom * self.ty
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn textures_are_deterministic_varied_and_in_range() {
        let a = procedural(11, 3, 48, 64, 64.0);
        let b = procedural(11, 3, 48, 64, 64.0);
        let c = procedural(12, 3, 48, 64, 64.0);
        assert_eq!(a, b);
        assert_ne!(a, c);
        assert!(a.data().iter().all(|v| (0.0..=1.0).contains(v)));
        // Not flat: a real spread of values in each texture.
        for img in [&a, &c] {
            let (lo, hi) = img
                .data()
                .iter()
                .fold((1.0f32, 0.0f32), |(l, h), &v| (l.min(v), h.max(v)));
            assert!(hi - lo > 0.2, "flat texture {lo}..{hi}");
        }
        let grey = procedural(11, 1, 8, 8, 16.0);
        assert_eq!(grey.channels(), 1);
    }

    /// The mirror-only sample the corners' fast path replaced, kept as the reference.
    fn mirrored_sample(img: &Image, c: usize, x: f32, y: f32) -> f32 {
        let (h, w) = (img.height(), img.width());
        let (xf, yf) = (x.floor(), y.floor());
        let (tx, ty) = (x - xf, y - yf);
        let m = |i: f32, n: usize| crate::imaging::convolve::mirror(i as isize, n);
        let (x0, x1) = (m(xf, w), m(xf + 1.0, w));
        let (y0, y1) = (m(yf, h), m(yf + 1.0, h));
        let p = img.plane(c);
        let top = p[y0 * w + x0] * (1.0 - tx) + p[y0 * w + x1] * tx;
        let bottom = p[y1 * w + x0] * (1.0 - tx) + p[y1 * w + x1] * tx;
        top * (1.0 - ty) + bottom * ty
    }

    /// One channel and all channels at once give the mirror-only sample's bits: inside, on
    /// and just inside the last row and column, mirrored outside, at −0, far away, and on
    /// one-pixel rasters; a grey texture fills every channel.
    #[test]
    fn samples_equal_the_mirrored_reference_bit_for_bit() {
        let below = |v: f32| f32::from_bits(v.to_bits() - 1);
        let xs = [
            0.0,
            -0.0,
            3.25,
            11.0,
            12.0,
            below(12.0),
            below(11.0),
            -2.3,
            30.7,
            -1e9,
            1e30,
        ];
        let ys = [0.0, -0.0, 4.5, 7.0, 8.0, below(8.0), -9.2, 1e9];
        for img in [procedural(5, 3, 9, 13, 8.0), procedural(7, 3, 1, 1, 8.0)] {
            let grey = procedural(6, 1, img.height(), img.width(), 8.0);
            for &x in &xs {
                for &y in &ys {
                    let mut out = [0.5f32; 3];
                    add_bilinear(&img, x, y, &mut out);
                    for (c, v) in out.iter().enumerate() {
                        let want = mirrored_sample(&img, c, x, y);
                        assert_eq!(sample_bilinear(&img, c, x, y).to_bits(), want.to_bits());
                        assert_eq!(v.to_bits(), (0.5 + want).to_bits(), "({x}, {y}) {c}");
                    }
                    let mut out = [0.0f32; 3];
                    add_bilinear(&grey, x, y, &mut out);
                    assert_eq!(out, [mirrored_sample(&grey, 0, x, y); 3]);
                }
            }
        }
    }

    #[test]
    fn bilinear_sampling_interpolates_and_mirrors() {
        let img = Image::from_vec(1, 2, 2, vec![0.0, 1.0, 2.0, 3.0]).unwrap();
        assert_eq!(sample_bilinear(&img, 0, 0.5, 0.5), 1.5);
        assert_eq!(sample_bilinear(&img, 0, 1.0, 0.0), 1.0);
        assert!(sample_bilinear(&img, 0, -5.3, 9.1).is_finite());
    }
}
