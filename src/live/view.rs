//! The browser view's frame (Fig. S11's drawing): the processed frame with each track's centre,
//! ID and predicted path, and the flow's colour wheel beside it, as one JPEG.

use crate::error::{Error, Result};
use crate::flow::viz::flow_to_image;
use crate::types::{Flow, Image};

use super::tracking::Object;

/// The frame and the flow side by side, tracks drawn on the frame, encoded as JPEG.
pub fn render_view(frame: &Image, flow: &Flow, objects: &[Object]) -> Result<Vec<u8>> {
    let (h, w) = (frame.height(), frame.width());
    let wheel = flow_to_image(flow, None);
    let mut rgb = vec![0u8; h * 2 * w * 3];
    let to8 = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    for y in 0..h {
        for x in 0..w {
            for c in 0..3 {
                let fc = c.min(frame.channels() - 1);
                rgb[(y * 2 * w + x) * 3 + c] = to8(frame.get(fc, y, x));
                if wheel.height() == h && wheel.width() == w {
                    rgb[(y * 2 * w + w + x) * 3 + c] = to8(wheel.get(c, y, x));
                }
            }
        }
    }
    let mut canvas = Canvas {
        rgb: &mut rgb,
        w: 2 * w,
        h,
    };
    for o in objects {
        let colour = palette(o.id);
        for p in &o.path {
            canvas.dot(p[0], p[1], 1, colour);
        }
        canvas.cross(o.centroid[0], o.centroid[1], 5, colour);
        canvas.number(o.centroid[0] + 7.0, o.centroid[1] - 7.0, o.id, colour);
    }
    let mut out = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, 80)
        .encode(
            &rgb,
            (2 * w) as u32,
            h as u32,
            image::ExtendedColorType::Rgb8,
        )
        .map_err(|e| Error::invalid("view frame", format!("JPEG encoding failed: {e}")))?;
    Ok(out)
}

fn palette(id: usize) -> [u8; 3] {
    const P: [[u8; 3]; 6] = [
        [255, 40, 40],
        [40, 220, 40],
        [60, 120, 255],
        [255, 200, 0],
        [255, 0, 255],
        [0, 230, 230],
    ];
    P[id % P.len()]
}

struct Canvas<'a> {
    rgb: &'a mut [u8],
    w: usize,
    h: usize,
}

impl Canvas<'_> {
    fn put(&mut self, x: i64, y: i64, c: [u8; 3]) {
        if x >= 0 && y >= 0 && (x as usize) < self.w && (y as usize) < self.h {
            let i = (y as usize * self.w + x as usize) * 3;
            self.rgb[i..i + 3].copy_from_slice(&c);
        }
    }

    fn dot(&mut self, x: f64, y: f64, r: i64, c: [u8; 3]) {
        if !(x.is_finite() && y.is_finite()) {
            return;
        }
        let (cx, cy) = (x.round() as i64, y.round() as i64);
        for dy in -r..=r {
            for dx in -r..=r {
                self.put(cx + dx, cy + dy, c);
            }
        }
    }

    fn cross(&mut self, x: f64, y: f64, r: i64, c: [u8; 3]) {
        if !(x.is_finite() && y.is_finite()) {
            return;
        }
        let (cx, cy) = (x.round() as i64, y.round() as i64);
        for d in -r..=r {
            self.put(cx + d, cy, c);
            self.put(cx, cy + d, c);
        }
    }

    /// A number in a 3×5 pixel font, doubled.
    fn number(&mut self, x: f64, y: f64, n: usize, c: [u8; 3]) {
        const DIGITS: [u16; 10] = [
            0o75557, 0o26222, 0o71747, 0o71717, 0o55711, 0o74717, 0o74757, 0o71111, 0o75757,
            0o75717,
        ];
        if !(x.is_finite() && y.is_finite()) {
            return;
        }
        let (x0, y0) = (x.round() as i64, y.round() as i64);
        for (k, ch) in n.to_string().bytes().enumerate() {
            let bits = DIGITS[(ch - b'0') as usize];
            for row in 0..5 {
                let r = (bits >> (3 * (4 - row))) & 0o7;
                for col in 0..3 {
                    if r & (4 >> col) != 0 {
                        for s in 0..4 {
                            self.put(x0 + k as i64 * 8 + col * 2 + s % 2, y0 + row * 2 + s / 2, c);
                        }
                    }
                }
            }
        }
    }
}
