//! Stage 1, detection (Note S13's region of interest, Eqs. S17–S19): one frame step's flow and
//! frames become regions, each an object's centre, speed and direction, confirmed against the
//! frames. It imports nothing from the later stages (`motion`, `tracker`, `eval`). Its files,
//! in the order a frame goes through them:
//!
//! - `pipeline.rs`: `detect`, one frame's detection from end to end.
//! - `detect_config.rs`: `DetectConfig`, the detector's settings and their checks.
//! - `background.rs`: the background's global motion (affine or translation, IRLS with Huber).
//! - `noise_floor.rs`: a frame's robust noise floor (median + k · 1.4826 MAD).
//! - `roi.rs`: thresholded 8-connected regions, centroid, speed, circular mean direction.
//! - `change.rs`: the change test, where the frames changed (motion compensated).
//! - `grow.rs`: change seeds grown to their object's extent in the flow.
//! - `trim.rs`: a grown region trimmed of the halo the background's motion explains.
//! - `photometric.rs`: grey frames and the photometric (warp residual) test.
//! - `align.rs`: the region's motion that the frames confirm (colour alignment).
//! - `retry.rs`: a failed photometric test retried with the aligned motion (weak detections).
//! - `placement.rs`: the placement's frames, settings and verdicts.
//! - `noise_level.rs`: the camera's noise level function, measured on the still background.
//! - `foreground.rs`: frame n's foreground against the still background, the mean shift.
//! - `still_background.rs`: the still camera's background, a region placed on its object.
//! - `split.rs`: a merged region split between the tracks' seeds it covers.
//! - `static_flow.rs`: the background-flow magnitude of a flow over a clip's static pixels.

pub mod align;
pub mod background;
pub mod change;
pub mod detect_config;
pub mod foreground;
pub mod grow;
pub mod noise_floor;
pub mod noise_level;
pub mod photometric;
pub mod pipeline;
pub mod placement;
pub mod retry;
pub mod roi;
pub mod split;
pub mod static_flow;
pub mod still_background;
pub mod trim;

pub use detect_config::DetectConfig;
pub use pipeline::{Candidate, FrameDetection, detect};
