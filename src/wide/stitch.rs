//! Stitching (Note S3, Fig. S3a): every pixel of the 480×1440 output takes its raw-sensor
//! position from its lens's calibrated polynomials, precomputed once as a map, and is sampled
//! bilinearly; the rectified sub-images sit side by side as contiguous angular segments.

use rayon::prelude::*;

use super::calibrate::Calibration;
use crate::error::{Error, Result};
use crate::scene::texture::sample_bilinear;
use crate::types::Image;

/// A precomputed rectification map.
pub struct Stitcher {
    height: usize,
    width: usize,
    sensor: [usize; 2],
    /// Raw `(x, y)` of every output pixel, row-major.
    map: Vec<(f32, f32)>,
}

impl Stitcher {
    /// Builds the map of `calib`.
    pub fn new(calib: &Calibration) -> Result<Self> {
        calib.layout.validate()?;
        if calib.lenses.len() != calib.layout.lenses.len() {
            return Err(Error::invalid(
                "calibration",
                format!(
                    "{} lens fits for a layout of {} lenses",
                    calib.lenses.len(),
                    calib.layout.lenses.len()
                ),
            ));
        }
        for (k, l) in calib.lenses.iter().enumerate() {
            l.fx.validate(&format!("calibration lens {k} fx"))?;
            l.fy.validate(&format!("calibration lens {k} fy"))?;
        }
        let [h, w] = calib.layout.wide_size();
        let n = calib.layout.tile_px;
        let map = (0..h * w)
            .into_par_iter()
            .map(|i| {
                let (x, y) = ((i % w) as f64, (i / w) as f64);
                let l = &calib.lenses[((i % w) / n).min(calib.lenses.len() - 1)];
                (l.fx.eval(x, y) as f32, l.fy.eval(x, y) as f32)
            })
            .collect();
        Ok(Self {
            height: h,
            width: w,
            sensor: calib.layout.sensor,
            map,
        })
    }

    /// Rectifies and joins one raw frame into the stitched image.
    pub fn apply(&self, raw: &Image) -> Result<Image> {
        let [sh, sw] = self.sensor;
        if (raw.height(), raw.width()) != (sh, sw) {
            return Err(Error::shape(
                "raw frame",
                format!("{sw}x{sh} (the calibrated sensor)"),
                format!("{}x{}", raw.width(), raw.height()),
            ));
        }
        let c = raw.channels();
        let n = self.height * self.width;
        let mut data = vec![0.0f32; c * n];
        for ch in 0..c {
            data[ch * n..(ch + 1) * n]
                .par_iter_mut()
                .zip(&self.map)
                .for_each(|(o, &(x, y))| {
                    *o = if x >= 0.0 && y >= 0.0 && x <= (sw - 1) as f32 && y <= (sh - 1) as f32 {
                        sample_bilinear(raw, ch, x, y)
                    } else {
                        0.0
                    };
                });
        }
        Image::from_vec(c, self.height, self.width, data)
    }
}
