//! The pixel budget: every image and flow reader checks the size a file declares against it
//! before decoding or allocating its pixels, so a small file that claims a huge size is refused
//! at once, cheaply, instead of exhausting memory.
//!
//! One process-wide value, [`DEFAULT_MAX_PIXELS`] unless [`set_max_pixels`] changed it (the
//! CLI's global `--max-pixels N` flag).

use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::{Error, Result};

/// Default pixel budget: 64 megapixels (W·H ≤ 64 000 000).
///
/// Why this number: the camera pipeline (read, brightness, FFT blur with the 129×129 metalens
/// PSF, noise, gamma, quantisation, write) peaks at about 97 bytes per RGB pixel (measured with
/// `pins simulate` on a 4096×4096 RGB frame: 1.62 GB resident; 34 bytes per grey pixel). A
/// 64 MP RGB frame therefore needs about 6.2 GB and the two frames of a flow pair about
/// 12.5 GB, which leaves room on a 24 GB machine for the flow network's per-pixel buffers
/// (its all-pairs correlation grows with the square of the pixel count, so very large inputs
/// are bounded by the network's own checks, not by this budget). It admits every input we
/// know of: the 1600×1200 sensor, KITTI, Sintel, 8K video frames (33 MP) and 61 MP
/// full-frame photographs. Raise it with `--max-pixels N` for bigger files.
pub const DEFAULT_MAX_PIXELS: u64 = 64_000_000;

/// Samples per pixel the budget allows: a file may declare at most
/// `BUDGET_CHANNELS × budget` samples (W·H·C), so RGBA at full budget is fine but a file
/// declaring hundreds of channels of a budget-sized layer is not.
pub const BUDGET_CHANNELS: u64 = 4;

/// The command-line flag that raises the budget, named in every refusal.
pub const MAX_PIXELS_FLAG: &str = "--max-pixels";

static MAX_PIXELS: AtomicU64 = AtomicU64::new(DEFAULT_MAX_PIXELS);

/// Sets the process-wide pixel budget (pixels, W·H) checked by every reader from now on.
/// `0` refuses every image.
pub fn set_max_pixels(n: u64) {
    MAX_PIXELS.store(n, Ordering::Relaxed);
}

/// The current process-wide pixel budget (pixels, W·H).
pub fn max_pixels() -> u64 {
    MAX_PIXELS.load(Ordering::Relaxed)
}

/// Refuses a file whose header declares `width × height` pixels of `channels` samples when that
/// exceeds the pixel budget. `what` names the format (e.g. "PNG image", ".flo flow"). Cheap:
/// call it right after reading the header, before allocating anything for the pixels.
pub fn check_pixels(path: &Path, what: &str, width: u64, height: u64, channels: u64) -> Result<()> {
    let budget = max_pixels();
    let pixels = u128::from(width) * u128::from(height);
    let samples = pixels * u128::from(channels.max(1));
    let sample_budget = u128::from(budget) * u128::from(BUDGET_CHANNELS);
    if pixels <= u128::from(budget) && samples <= sample_budget {
        return Ok(());
    }
    let mp = |n: u128| n as f64 / 1e6;
    let over = if pixels > u128::from(budget) {
        format!(
            "{:.1} megapixels, over the pixel budget of {budget} pixels ({:.1} MP)",
            mp(pixels),
            mp(u128::from(budget))
        )
    } else {
        format!(
            "{samples} samples, over the budget of {sample_budget} samples \
             ({BUDGET_CHANNELS} channels × {budget} pixels)"
        )
    };
    Err(Error::format(
        path,
        format!(
            "{what} declares {width}x{height} pixels with {channels} channel(s): {over}; \
             refused before decoding. If the file is genuine, raise the budget with \
             {MAX_PIXELS_FLAG} N"
        ),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refusal_names_file_size_and_flag() {
        // The budget is process-wide; this test only reads it and checks sizes around it.
        let b = max_pixels();
        assert!(check_pixels(Path::new("ok.png"), "PNG image", 1, b, 1).is_ok());
        let e = check_pixels(Path::new("big.png"), "PNG image", 16000, 16000, 1)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("big.png") && e.contains("16000x16000") && e.contains("--max-pixels"),
            "{e}"
        );
        // Overflow-proof for absurd headers, and too many channels of a legal size.
        assert!(check_pixels(Path::new("x"), "x", u64::MAX, u64::MAX, u64::MAX).is_err());
        let e = check_pixels(Path::new("c.exr"), "EXR", 1, b, 5).unwrap_err();
        assert!(e.to_string().contains("samples"), "{e}");
        assert!(check_pixels(Path::new("c.exr"), "EXR", 1, b / 5, 5).is_ok());
    }
}
