//! KITTI 16-bit PNG optical flow: `u = (R - 2^15) / 64`, `v = (G - 2^15) / 64`, valid = `B > 0`.

use std::io::Cursor;
use std::path::Path;

use image::{ColorType, DynamicImage, ImageBuffer, ImageDecoder, ImageFormat};

use super::atomic::{read_bytes, write_bytes_atomic};
use super::image::{decode_raster, open_raster};
use super::unknown::is_unknown;
use crate::error::{Error, Result};
use crate::types::Flow;

const OFFSET: f32 = 32768.0;
const SCALE: f32 = 64.0;

/// Reads a KITTI flow PNG. Returns the flow (NaN where invalid) and the validity mask
/// (row-major, `true` where `B > 0`). 8-bit or non-RGB PNGs are rejected from their header,
/// and the declared size is checked against the pixel budget, before decoding.
pub fn read_kitti_flow(path: &Path) -> Result<(Flow, Vec<bool>)> {
    decode_kitti_flow(&read_bytes(path)?, path)
}

/// Decodes the bytes of a KITTI flow PNG as [`read_kitti_flow`] does; `path` is used only in
/// error messages.
pub fn decode_kitti_flow(bytes: &[u8], path: &Path) -> Result<(Flow, Vec<bool>)> {
    let (decoder, format) = open_raster(bytes, path)?;
    let color = decoder.color_type();
    if color != ColorType::Rgb16 {
        return Err(Error::format(
            path,
            format!("a KITTI flow PNG must be 16-bit RGB, found {color:?}"),
        ));
    }
    let img = decode_raster(decoder, format, path)?;
    let DynamicImage::ImageRgb16(buf) = img else {
        return Err(Error::format(
            path,
            format!(
                "a KITTI flow PNG must be 16-bit RGB, found {:?}",
                img.color()
            ),
        ));
    };
    let (w, h) = (buf.width() as usize, buf.height() as usize);
    let n = w * h;
    let mut data = vec![f32::NAN; 2 * n];
    let mut valid = vec![false; n];
    let (u, v) = data.split_at_mut(n);
    for (i, px) in buf.as_raw().chunks_exact(3).take(n).enumerate() {
        if px[2] > 0 {
            u[i] = (f32::from(px[0]) - OFFSET) / SCALE;
            v[i] = (f32::from(px[1]) - OFFSET) / SCALE;
            valid[i] = true;
        }
    }
    let flow = Flow::from_vec(h, w, data)
        .map_err(|e| Error::format(path, format!("decoded PNG has an inconsistent size: {e}")))?;
    Ok((flow, valid))
}

/// Encodes one component: `round(x * 64 + 2^15)` clamped to 0..=65535, i.e. about
/// -512..=511.98 pixels.
fn encode_component(x: f32) -> u16 {
    (x * SCALE + OFFSET).round().clamp(0.0, 65535.0) as u16
}

/// Writes a KITTI flow PNG atomically. Unknown vectors (a component non-finite or of magnitude
/// `>= 1e9`, see [`is_unknown`]) are written as invalid (`B = 0`); others are clamped to the
/// representable range and marked valid.
pub fn write_kitti_flow(path: &Path, flow: &Flow) -> Result<()> {
    let (w, h) = (flow.width(), flow.height());
    if w == 0 || h == 0 || w > u32::MAX as usize || h > u32::MAX as usize {
        return Err(Error::invalid(
            format!("flow for {}", path.display()),
            format!("cannot write a KITTI PNG of size {w}x{h}"),
        ));
    }
    let mut raw = Vec::with_capacity(3 * w * h);
    for (&a, &b) in flow.u().iter().zip(flow.v()) {
        if !is_unknown(a, b) {
            raw.extend_from_slice(&[encode_component(a), encode_component(b), 1]);
        } else {
            raw.extend_from_slice(&[0, 0, 0]);
        }
    }
    let buf: ImageBuffer<image::Rgb<u16>, Vec<u16>> =
        ImageBuffer::from_raw(w as u32, h as u32, raw).ok_or_else(|| {
            Error::invalid(
                format!("flow for {}", path.display()),
                "buffer size mismatch",
            )
        })?;
    let mut cur = Cursor::new(Vec::new());
    DynamicImage::ImageRgb16(buf)
        .write_to(&mut cur, ImageFormat::Png)
        .map_err(|e| {
            Error::invalid(
                format!("flow for {}", path.display()),
                format!("PNG encoding: {e}"),
            )
        })?;
    write_bytes_atomic(path, &cur.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::{BitDepth, write_image};
    use crate::types::Image;

    #[test]
    fn round_trip_with_invalid_pixels() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("f.png");
        let mut f = Flow::zeros(3, 4);
        f.set(0, 0, 1.5, -2.25);
        f.set(1, 2, -100.0, 37.015625);
        f.set(2, 3, f32::NAN, 1.0);
        f.set(2, 1, 4.0, f32::INFINITY);
        f.set(0, 3, 1000.0, -1000.0);
        write_kitti_flow(&p, &f).unwrap();
        let (back, valid) = read_kitti_flow(&p).unwrap();
        assert_eq!(valid.iter().filter(|&&m| !m).count(), 2);
        assert!(!valid[2 * 4 + 3] && !valid[2 * 4 + 1]);
        assert_eq!(back.valid_mask(), valid);
        assert_eq!(back.get(0, 0), (1.5, -2.25));
        assert_eq!(back.get(1, 2), (-100.0, 37.015625));
        assert_eq!(back.get(1, 1), (0.0, 0.0));
        let (u, v) = back.get(0, 3);
        assert_eq!((u, v), ((65535.0 - 32768.0) / 64.0, -512.0));
        assert!(back.get(2, 3).0.is_nan());
    }

    #[test]
    fn rejects_eight_bit_and_grey() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("rgb8.png");
        write_image(&p, &Image::filled(3, 2, 2, 0.5), BitDepth::Eight).unwrap();
        let e = read_kitti_flow(&p).unwrap_err().to_string();
        assert!(e.contains("16-bit RGB") && e.contains("rgb8.png"), "{e}");
        let p = dir.path().join("grey16.png");
        write_image(&p, &Image::filled(1, 2, 2, 0.5), BitDepth::Sixteen).unwrap();
        assert!(read_kitti_flow(&p).is_err());
    }
}
