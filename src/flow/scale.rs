//! Flow at another resolution (the whole system's speed and accuracy knob, Notes S13–S15):
//! both frames resampled by `scale` (area-averaged below 1, bilinear above), MMS run on them, and
//! the flow brought back to the frames' size with its vectors multiplied by the size ratio, so
//! a tracker and its truth keep working in the full frame's pixels. Below 1 the network runs
//! faster; above 1 it sees small movers larger (it estimates at 1/8 of its input, where an
//! 18-px disc is 4 cells wide), at the square of the scale in time.

use super::infer::Predictor;
use super::resample::resize_flow;
use crate::error::{Error, Result};
use crate::imaging::resize::{resize_to, scaled_size};
use crate::types::{Flow, Image};

/// The largest `scale` (16 times the pixels).
pub const MAX_SCALE: f64 = 4.0;

/// Checks that `scale` is in (0, [`MAX_SCALE`]].
pub fn check_scale(scale: f64) -> Result<()> {
    if scale.is_finite() && scale > 0.0 && scale <= MAX_SCALE {
        Ok(())
    } else {
        Err(Error::invalid(
            "scale",
            format!("must be in (0, {MAX_SCALE}], got {scale}"),
        ))
    }
}

/// The flow from `img1` to `img2` estimated at `scale` ∈ (0, 4] of their size, returned at
/// their size. A scale that leaves the size as it is runs `Predictor::predict` itself.
pub fn predict_scaled(
    predictor: &Predictor,
    img1: &Image,
    img2: &Image,
    iters: usize,
    scale: f64,
) -> Result<Flow> {
    check_scale(scale)?;
    let (_, h, w) = img1.shape();
    let (sh, sw) = scaled_size(h, w, scale);
    if (sh, sw) == (h, w) {
        return predictor.predict(img1, img2, iters);
    }
    let (a, b) = (resize_to(img1, sh, sw)?, resize_to(img2, sh, sw)?);
    resize_flow(&predictor.predict(&a, &b, iters)?, h, w)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scales_outside_the_range_are_refused() {
        assert!(check_scale(1.5).is_ok() && check_scale(4.0).is_ok());
        assert!(check_scale(0.0).is_err() && check_scale(-1.0).is_err());
        assert!(check_scale(4.5).is_err() && check_scale(f64::NAN).is_err());
    }
}
