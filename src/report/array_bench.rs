//! Error against run time for the array (Note S3): for each polynomial order, the reprojection
//! error on the grid dots (all and held out) and the time to stitch one raw frame on one core.

use serde::Serialize;

use super::timing::median_ms;
use crate::error::{Error, Result};
use crate::types::Image;
use crate::wide::calibrate::{calibrate_from_dots, detect_dots};
use crate::wide::layout::ArrayLayout;
use crate::wide::stitch::Stitcher;

/// One row of the table.
#[derive(Clone, Debug, Serialize)]
pub struct OrderRow {
    pub order: usize,
    /// Worst lens's RMS and maximum reprojection error on the dots, pixels.
    pub rms_px: f64,
    pub max_px: f64,
    /// Worst lens's 5-fold held-out RMS, pixels.
    pub held_out_rms_px: f64,
    /// Median milliseconds to stitch one frame on one thread (map precomputed).
    pub stitch_ms: f64,
    pub frames_per_s: f64,
}

/// Calibrates at every order 2…6 and times the stitch of `raw_grid` itself on one thread.
pub fn orders_table(
    layout: &ArrayLayout,
    raw_grid: &Image,
    per_side: usize,
    reps: usize,
) -> Result<Vec<OrderRow>> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .map_err(|e| Error::invalid("threads", e.to_string()))?;
    let dots = detect_dots(layout, raw_grid)?;
    let mut rows = Vec::new();
    for order in 2..=6 {
        let calib = calibrate_from_dots(layout, &dots, per_side, Some(order))?;
        let stitcher = Stitcher::new(&calib)?;
        let stitch_ms = pool.install(|| median_ms(reps, || stitcher.apply(raw_grid)));
        let worst = |f: &dyn Fn(&crate::wide::calibrate::LensCalibration) -> f64| {
            calib.lenses.iter().map(f).fold(0.0, f64::max)
        };
        rows.push(OrderRow {
            order,
            rms_px: worst(&|l| l.rms_px),
            max_px: worst(&|l| l.max_px),
            held_out_rms_px: worst(&|l| l.held_out.first().map_or(f64::NAN, |h| h.1)),
            stitch_ms,
            frames_per_s: 1e3 / stitch_ms,
        });
    }
    Ok(rows)
}
