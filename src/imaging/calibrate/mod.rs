//! Fitting the camera model (Notes S4–S5) to a real camera: the noise of Eq. S3 from
//! flat-field captures (photon transfer), the PSF from captures of a point source.
//!
//! - `line_fit.rs`: the robust weighted line σ² = a·μ + b with confidence intervals.
//! - `photon_transfer.rs`: levels' mean and temporal variance from captures, the fit per
//!   channel and pooled.
//! - `captures.rs`: a folder of captures grouped into levels, dark frames, refused encodings.
//! - `point_source.rs`: a PSF from captures of a point source at one or more exposures.
//! - `support.rs`: where the source's energy lies (support, centroid, radius) and Lanczos-3
//!   resampling.

pub mod captures;
pub mod line_fit;
pub mod photon_transfer;
pub mod point_source;
mod support;
