//! A folder of flat-field captures for photon transfer (EMVA 1288; Note S4's Eq. S3): files
//! named `LEVEL_N.png` are grouped by `LEVEL` (two or more captures of each exposure or
//! brightness), files named `dark_N.png` are dark frames. Integer rasters only (PNG, TIFF,
//! PPM, 8 or 16 bits): a JPEG's compression removes the very noise the fit measures, and is
//! refused with that reason.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use super::photon_transfer::{Encoding, Level, level_stats};
use crate::error::{Error, Result};
use crate::io::{BitDepth, image_files, read_capture};
use crate::types::Image;

/// The captures of one folder.
#[derive(Clone, Debug, PartialEq)]
pub struct CaptureSet {
    /// Level name → its captures, in name order.
    pub levels: BTreeMap<String, Vec<PathBuf>>,
    pub dark: Vec<PathBuf>,
}

/// Groups the image files of `dir` by the part of their name before the last `_`.
pub fn group(dir: &Path) -> Result<CaptureSet> {
    let files = image_files(dir)?;
    let mut levels: BTreeMap<String, Vec<PathBuf>> = BTreeMap::new();
    let mut dark = Vec::new();
    for f in files {
        let stem = f
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let Some((level, _)) = stem.rsplit_once('_') else {
            return Err(Error::invalid(
                "captures",
                format!(
                    "{}: name it LEVEL_N (e.g. exp010_0.png, exp010_1.png; dark_0.png for a \
                     dark frame) so that captures of one level group together",
                    f.display()
                ),
            ));
        };
        if level == "dark" {
            dark.push(f);
        } else {
            levels.entry(level.to_string()).or_default().push(f);
        }
    }
    if levels.is_empty() {
        return Err(Error::invalid(
            "captures",
            format!(
                "{} holds no flat-field captures (LEVEL_N.png)",
                dir.display()
            ),
        ));
    }
    Ok(CaptureSet { levels, dark })
}

/// Reads one capture, refusing what the fit cannot use, and checks it against the first
/// capture's shape and depth (`expect`).
fn read(path: &Path, expect: &mut Option<((usize, usize, usize), BitDepth)>) -> Result<Image> {
    let (image, depth, jpeg) = read_capture(path)?;
    if jpeg {
        return Err(Error::format(
            path,
            "a JPEG: its compression smooths away the temporal noise that photon transfer \
             measures, so no fit from it can be trusted; capture raw or lossless frames (PNG, \
             TIFF), e.g. with the camera's JPEG quality off or a raw readout",
        ));
    }
    let Some(depth) = depth else {
        return Err(Error::format(
            path,
            "float samples: photon transfer needs the sensor's integer codes (8- or 16-bit \
             PNG, TIFF or PPM)",
        ));
    };
    let shape = image.shape();
    match expect {
        None => *expect = Some((shape, depth)),
        Some((s, d)) if *s != shape || *d != depth => {
            return Err(Error::invalid(
                "captures",
                format!(
                    "{} is {}×{}×{} at {} bits, the first capture {}×{}×{} at {} bits: every \
                     capture must come from one camera setting",
                    path.display(),
                    shape.0,
                    shape.1,
                    shape.2,
                    bits(depth),
                    s.0,
                    s.1,
                    s.2,
                    bits(*d)
                ),
            ));
        }
        Some(_) => {}
    }
    Ok(image)
}

fn bits(d: BitDepth) -> u8 {
    match d {
        BitDepth::Eight => 8,
        BitDepth::Sixteen => 16,
    }
}

/// Every level's statistics per channel, captures encoded by Eq. S4 with `gamma`; the dark
/// frames (when there are two or more) give the offset taken off every mean and a level of
/// their own at zero signal.
pub fn measure(set: &CaptureSet, gamma: f64) -> Result<Vec<Level>> {
    let mut expect = None;
    let mut load = |paths: &[PathBuf]| -> Result<(Vec<Image>, Encoding)> {
        let frames = paths
            .iter()
            .map(|p| read(p, &mut expect))
            .collect::<Result<Vec<_>>>()?;
        Ok((frames, encoding(gamma, &expect)))
    };
    let mut levels = Vec::new();
    let mut offset = None;
    if !set.dark.is_empty() {
        let (frames, enc) = load(&set.dark)?;
        let mut dark = level_stats("dark", &frames, enc, None)?;
        // A dark level clipped at the lowest code (a sensor without a black level) has a
        // mean the clipping raised: no offset is taken from it.
        if dark.iter().all(|l| l.excluded.is_none()) {
            offset = Some(dark.iter().map(|l| l.mean).collect::<Vec<_>>());
            dark.iter_mut().for_each(|l| l.mean = 0.0);
        } else {
            for l in &mut dark {
                l.excluded = Some(format!(
                    "{}; no dark offset taken",
                    l.excluded.as_deref().unwrap_or("another channel clipped")
                ));
            }
        }
        levels.extend(dark);
    }
    for (name, paths) in &set.levels {
        let (frames, enc) = load(paths)?;
        levels.extend(level_stats(name, &frames, enc, offset.as_deref())?);
    }
    Ok(levels)
}

fn encoding(gamma: f64, expect: &Option<((usize, usize, usize), BitDepth)>) -> Encoding {
    Encoding {
        gamma,
        bits: expect.map_or(8, |(_, d)| bits(d)),
    }
}
