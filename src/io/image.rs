//! Raster images (PNG, JPEG, PPM/PGM, TIFF via the `image` crate; EXR, NPY, PFM by extension)
//! read into and written from planar [`Image`]s scaled to [0, 1].

use std::io::Cursor;
use std::path::Path;

use image::{DynamicImage, ImageBuffer, ImageDecoder, ImageFormat, ImageReader, Limits};

use super::atomic::{read_bytes, write_bytes_atomic};
use super::npy::decode_npy;
use super::pfm::decode_pfm;
use super::{budget, exr, ext_lower, raster_guard, write_exr, write_npy, write_pfm};
use crate::error::{Error, Result};
use crate::types::Image;

/// Sample depth of integer raster files written by [`write_image`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BitDepth {
    /// 8 bits per sample (0..=255).
    Eight,
    /// 16 bits per sample (0..=65535).
    Sixteen,
}

const WRITE_EXTS: &str = "png, ppm, pgm, pnm, jpg, jpeg, tif, tiff, exr, pfm, npy";

/// Reads an image as planar `[C, H, W]`: grey (with or without alpha) gives 1 channel, colour
/// gives 3 (alpha is dropped). 8-bit samples are divided by 255, 16-bit by 65535, float
/// samples are kept. `.exr`, `.npy` and `.pfm` go to their own readers; other files are
/// recognised by content (PNG, JPEG, PPM/PGM, TIFF), falling back to the extension. The size
/// the file declares is checked against the pixel budget ([`super::budget`]) before decoding.
pub fn read_image(path: &Path) -> Result<Image> {
    decode_image(&read_bytes(path)?, path)
}

/// A raster capture as [`read_image`] reads it, with its integer sample depth (`None` for
/// float formats) and whether it is a JPEG (lossy: its pixels are not the sensor's).
pub fn read_capture(path: &Path) -> Result<(Image, Option<BitDepth>, bool)> {
    let bytes = read_bytes(path)?;
    match ext_lower(path).as_str() {
        "exr" | "npy" | "pfm" => Ok((decode_image(&bytes, path)?, None, false)),
        _ => {
            let img = decode_dynamic_bytes(&bytes, path)?;
            let jpeg = bytes.starts_with(&[0xFF, 0xD8]);
            let depth = match &img {
                DynamicImage::ImageLuma8(_)
                | DynamicImage::ImageLumaA8(_)
                | DynamicImage::ImageRgb8(_)
                | DynamicImage::ImageRgba8(_) => Some(BitDepth::Eight),
                DynamicImage::ImageLuma16(_)
                | DynamicImage::ImageLumaA16(_)
                | DynamicImage::ImageRgb16(_)
                | DynamicImage::ImageRgba16(_) => Some(BitDepth::Sixteen),
                _ => None,
            };
            Ok((dynamic_to_image(img, path)?, depth, jpeg))
        }
    }
}

/// Decodes the bytes of an image file as [`read_image`] does; `path` names the file in errors
/// and its extension picks the float formats.
pub fn decode_image(bytes: &[u8], path: &Path) -> Result<Image> {
    match ext_lower(path).as_str() {
        "exr" => exr::decode_exr_as_image(bytes, path),
        "npy" => npy_as_image(decode_npy(bytes, path)?, path),
        "pfm" => decode_pfm(bytes, path),
        _ => dynamic_to_image(decode_dynamic_bytes(bytes, path)?, path),
    }
}

/// An `.npy` array as an image: 1 or 3 channels are kept, a fourth (alpha) is dropped, and two
/// (which no image has) are refused.
fn npy_as_image(im: Image, path: &Path) -> Result<Image> {
    match im.channels() {
        1 | 3 => Ok(im),
        4 => {
            let (_, h, w) = im.shape();
            let mut data = im.into_vec();
            data.truncate(3 * h * w);
            Image::from_vec(3, h, w, data)
        }
        c => Err(Error::format(
            path,
            format!(
                "an image needs 1 channel (grey), 3 (RGB) or 4 (RGBA), this .npy array has {c} \
                 channels of {}x{}",
                im.width(),
                im.height()
            ),
        )),
    }
}

/// Reads two images that must have the same width and height (e.g. the frames of a flow pair).
pub fn read_image_pair(a: &Path, b: &Path) -> Result<(Image, Image)> {
    let ia = read_image(a)?;
    let ib = read_image(b)?;
    if (ia.height(), ia.width()) != (ib.height(), ib.width()) {
        return Err(Error::shape(
            format!("image pair {} and {}", a.display(), b.display()),
            format!(
                "{}x{} (width x height of {})",
                ia.width(),
                ia.height(),
                a.display()
            ),
            format!(
                "{}x{} (width x height of {})",
                ib.width(),
                ib.height(),
                b.display()
            ),
        ));
    }
    Ok((ia, ib))
}

/// Writes an image with the format chosen by extension: `png`, `tif`/`tiff` (8 or 16 bit,
/// 1 channel grey, 3 RGB, 4 RGBA), `ppm`/`pgm`/`pnm` (binary P6/P5, 8 or 16 bit, no alpha),
/// `jpg`/`jpeg` (8 bit, 1 or 3 channels), and `exr`/`pfm`/`npy` (float, `depth` ignored).
/// Integer samples are `round(clamp(v, 0, 1) * max)`; non-finite samples are an error.
pub fn write_image(path: &Path, image: &Image, depth: BitDepth) -> Result<()> {
    let ext = ext_lower(path);
    match ext.as_str() {
        "exr" => return write_exr(path, image),
        "pfm" => return write_pfm(path, image),
        "npy" => return write_npy(path, image),
        "png" | "ppm" | "pgm" | "pnm" | "jpg" | "jpeg" | "tif" | "tiff" => {}
        _ => {
            return Err(Error::invalid(
                format!("image file name {}", path.display()),
                format!("unsupported extension {ext:?}; supported: {WRITE_EXTS}"),
            ));
        }
    }
    let what = format!("image for {}", path.display());
    let (c, h, w) = image.shape();
    if !matches!(c, 1 | 3 | 4) {
        return Err(Error::invalid(
            what,
            format!("raster files take 1 (grey), 3 (RGB) or 4 (RGBA) channels, image has {c}"),
        ));
    }
    if h == 0 || w == 0 || h > u32::MAX as usize || w > u32::MAX as usize {
        return Err(Error::invalid(
            what,
            format!("cannot write an image of size {w}x{h}"),
        ));
    }
    image.check_finite(&what)?;
    let bytes = match ext.as_str() {
        "ppm" | "pgm" | "pnm" => encode_pnm(image, &ext, depth, &what)?,
        "jpg" | "jpeg" => {
            if depth == BitDepth::Sixteen || c == 4 {
                return Err(Error::invalid(
                    what,
                    "JPEG stores only 8-bit grey or RGB (use PNG or TIFF for 16 bit or alpha)",
                ));
            }
            let dynimg = to_dynamic(image, depth);
            let mut buf = Vec::new();
            let enc = image::codecs::jpeg::JpegEncoder::new_with_quality(&mut buf, 95);
            dynimg
                .write_with_encoder(enc)
                .map_err(|e| Error::invalid(what, format!("JPEG encoding failed: {e}")))?;
            buf
        }
        _ => {
            let format = if ext == "png" {
                ImageFormat::Png
            } else {
                ImageFormat::Tiff
            };
            let mut cur = Cursor::new(Vec::new());
            to_dynamic(image, depth)
                .write_to(&mut cur, format)
                .map_err(|e| Error::invalid(what, format!("{format:?} encoding failed: {e}")))?;
            cur.into_inner()
        }
    };
    write_bytes_atomic(path, &bytes)
}

/// Decodes raster bytes (PNG, JPEG, PPM/PGM, TIFF) after checking the declared size against
/// the pixel budget; `path` names the file in errors and gives the format when the content
/// does not.
pub(crate) fn decode_dynamic_bytes(bytes: &[u8], path: &Path) -> Result<DynamicImage> {
    let (decoder, format) = open_raster(bytes, path)?;
    decode_raster(decoder, format, path)
}

/// A decoder for raster bytes whose header has been read and whose declared size fits the
/// pixel budget; nothing of the pixels is decoded yet.
pub(crate) fn open_raster<'a>(
    bytes: &'a [u8],
    path: &Path,
) -> Result<(impl ImageDecoder + 'a, ImageFormat)> {
    let mut reader = ImageReader::new(Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| Error::io(path, e))?;
    if reader.format().is_none()
        && let Ok(f) = ImageFormat::from_path(path)
    {
        reader.set_format(f);
    }
    let Some(format) = reader.format() else {
        return Err(Error::format(
            path,
            "unrecognised image format (readable: PNG, JPEG, PPM/PGM, TIFF, EXR, NPY, PFM)",
        ));
    };
    // The decoders' own allocation guard, set to what the pixel budget can need (16 bytes per
    // pixel: RGBA f32) plus room for their working buffers.
    let mut limits = Limits::default();
    limits.max_alloc = Some(
        budget::max_pixels()
            .saturating_mul(16)
            .saturating_add(64 << 20),
    );
    reader.limits(limits);
    if format == ImageFormat::Tiff {
        raster_guard::check_tiff(bytes, path)?;
    }
    let decoder = reader
        .into_decoder()
        .map_err(|e| Error::format(path, format!("cannot decode as {format:?}: {e}")))?;
    let (w, h) = decoder.dimensions();
    let channels = decoder.color_type().channel_count();
    if w == 0 || h == 0 {
        return Err(Error::format(
            path,
            format!("{format:?} image declares an empty size {w}x{h}"),
        ));
    }
    budget::check_pixels(
        path,
        &format!("{format:?} image"),
        u64::from(w),
        u64::from(h),
        u64::from(channels),
    )?;
    Ok((decoder, format))
}

/// Decodes the pixels of an opened raster (see [`open_raster`]).
pub(crate) fn decode_raster(
    decoder: impl ImageDecoder,
    format: ImageFormat,
    path: &Path,
) -> Result<DynamicImage> {
    DynamicImage::from_decoder(decoder)
        .map_err(|e| Error::format(path, format!("cannot decode as {format:?}: {e}")))
}

/// Planar copy of `keep` of the `stride` interleaved channels, each sample mapped by `f`.
fn planar<T: Copy>(
    raw: &[T],
    (w, h): (u32, u32),
    stride: usize,
    keep: usize,
    f: impl Fn(T) -> f32,
) -> Result<Image> {
    let n = w as usize * h as usize;
    let mut data = vec![0.0f32; keep * n];
    for (i, px) in raw.chunks_exact(stride).take(n).enumerate() {
        for c in 0..keep {
            data[c * n + i] = f(px[c]);
        }
    }
    Image::from_vec(keep, h as usize, w as usize, data)
}

/// Converts a decoded image to planar `[C, H, W]` in [0, 1] (floats as stored).
pub(crate) fn dynamic_to_image(img: DynamicImage, path: &Path) -> Result<Image> {
    let d = (img.width(), img.height());
    let s8 = |v: u8| f32::from(v) / 255.0;
    let s16 = |v: u16| f32::from(v) / 65535.0;
    let id = |v: f32| v;
    let out = match &img {
        DynamicImage::ImageLuma8(b) => planar(b.as_raw(), d, 1, 1, s8),
        DynamicImage::ImageLumaA8(b) => planar(b.as_raw(), d, 2, 1, s8),
        DynamicImage::ImageRgb8(b) => planar(b.as_raw(), d, 3, 3, s8),
        DynamicImage::ImageRgba8(b) => planar(b.as_raw(), d, 4, 3, s8),
        DynamicImage::ImageLuma16(b) => planar(b.as_raw(), d, 1, 1, s16),
        DynamicImage::ImageLumaA16(b) => planar(b.as_raw(), d, 2, 1, s16),
        DynamicImage::ImageRgb16(b) => planar(b.as_raw(), d, 3, 3, s16),
        DynamicImage::ImageRgba16(b) => planar(b.as_raw(), d, 4, 3, s16),
        DynamicImage::ImageRgb32F(b) => planar(b.as_raw(), d, 3, 3, id),
        DynamicImage::ImageRgba32F(b) => planar(b.as_raw(), d, 4, 3, id),
        other => planar(other.to_rgb32f().as_raw(), d, 3, 3, id),
    };
    out.map_err(|e| Error::format(path, format!("decoded image has an inconsistent size: {e}")))
}

/// Interleaved quantised samples of all channels: `round(clamp(v, 0, 1) * max)`.
fn quantise(image: &Image, max: f32) -> Vec<f32> {
    let (c, h, w) = image.shape();
    let mut out = Vec::with_capacity(c * h * w);
    for y in 0..h {
        for x in 0..w {
            for ch in 0..c {
                out.push((image.get(ch, y, x).clamp(0.0, 1.0) * max).round());
            }
        }
    }
    out
}

/// An 8- or 16-bit `DynamicImage` of 1, 3 or 4 channels (the caller checked the count).
fn to_dynamic(image: &Image, depth: BitDepth) -> DynamicImage {
    let (c, h, w) = image.shape();
    let (w, h) = (w as u32, h as u32);
    match depth {
        BitDepth::Eight => {
            let q: Vec<u8> = quantise(image, 255.0)
                .into_iter()
                .map(|v| v as u8)
                .collect();
            // from_raw only fails on a length mismatch, which quantise rules out.
            let fallback = || DynamicImage::new_luma8(w, h);
            match c {
                1 => ImageBuffer::from_raw(w, h, q).map(DynamicImage::ImageLuma8),
                3 => ImageBuffer::from_raw(w, h, q).map(DynamicImage::ImageRgb8),
                _ => ImageBuffer::from_raw(w, h, q).map(DynamicImage::ImageRgba8),
            }
            .unwrap_or_else(fallback)
        }
        BitDepth::Sixteen => {
            let q: Vec<u16> = quantise(image, 65535.0)
                .into_iter()
                .map(|v| v as u16)
                .collect();
            let fallback = || DynamicImage::new_luma16(w, h);
            match c {
                1 => ImageBuffer::from_raw(w, h, q).map(DynamicImage::ImageLuma16),
                3 => ImageBuffer::from_raw(w, h, q).map(DynamicImage::ImageRgb16),
                _ => ImageBuffer::from_raw(w, h, q).map(DynamicImage::ImageRgba16),
            }
            .unwrap_or_else(fallback)
        }
    }
}

/// Binary PGM (P5) or PPM (P6), 16-bit samples big-endian. `.ppm` expands grey to RGB;
/// `.pgm` needs one channel; `.pnm` follows the channel count.
fn encode_pnm(image: &Image, ext: &str, depth: BitDepth, what: &str) -> Result<Vec<u8>> {
    let (c, h, w) = image.shape();
    if c == 4 || (ext == "pgm" && c != 1) {
        return Err(Error::invalid(
            what,
            format!("{ext} cannot store {c} channels (PGM: 1, PPM: 1 or 3, no alpha)"),
        ));
    }
    let colour = ext == "ppm" || c == 3;
    let max: u32 = if depth == BitDepth::Eight { 255 } else { 65535 };
    let magic = if colour { "P6" } else { "P5" };
    let mut out = format!("{magic}\n{w} {h}\n{max}\n").into_bytes();
    let q = quantise(image, max as f32);
    let reps = if colour && c == 1 { 3 } else { 1 };
    for v in q {
        for _ in 0..reps {
            if max == 255 {
                out.push(v as u8);
            } else {
                out.extend_from_slice(&(v as u16).to_be_bytes());
            }
        }
    }
    Ok(out)
}

/// The image files of a folder (by extension: PNG, JPEG, PPM/PGM, TIFF, EXR), sorted by name;
/// other files (an index, a log) are left alone.
pub fn image_files(dir: &Path) -> Result<Vec<std::path::PathBuf>> {
    let mut v: Vec<std::path::PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| Error::io(dir, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.is_file()
                && matches!(
                    ext_lower(p).as_str(),
                    "png" | "jpg" | "jpeg" | "ppm" | "pgm" | "tif" | "tiff" | "exr"
                )
        })
        .collect();
    v.sort();
    Ok(v)
}

/// The image files of a folder of frames (PNG, JPEG, PPM/PGM, TIFF, EXR), sorted by name.
pub fn frame_files(dir: &Path) -> Result<Vec<std::path::PathBuf>> {
    let v = image_files(dir)?;
    if v.len() < 2 {
        return Err(Error::invalid(
            "frames",
            format!(
                "{}: need at least two images, found {}",
                dir.display(),
                v.len()
            ),
        ));
    }
    Ok(v)
}

#[cfg(test)]
mod tests;
