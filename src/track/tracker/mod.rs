//! Stage 3, the multi-object tracker (Note S13's many objects, Movie S2): one frame's regions
//! are associated with the tracks, which are born, confirmed, coast, end and are
//! re-identified, each with its motion predictor. It imports only from `detect` and `motion`.
//! Its files:
//!
//! - `tracker_config.rs`: the tracker's settings (`TrackerConfig`) and their defaults.
//! - `hungarian.rs`: optimal assignment with a gate.
//! - `appearance.rs`: a track's colour, its running mean and variance.
//! - `associate.rs` (tests in `associate/tests.rs`): gated assignment of detections to tracks,
//!   merges, weak detections.
//! - `consistency.rs`: the motion-consistency test of a tentative track.
//! - `reid.rs`: re-identification of an ended or coasting track.
//! - `multi.rs` (tests in `multi/tests.rs`, `multi/tests/identity.rs`): the tracker's frame step
//!   and track life; `multi/reidentify.rs`: an ID taken back at confirmation.
//! - `tracks.rs`: its output, `tracks.json` (`Tracks`, `ObjectTrack`, `FrameRecord`).

pub mod appearance;
pub mod associate;
pub mod consistency;
pub mod hungarian;
pub mod multi;
pub mod reid;
pub mod tracker_config;
pub mod tracks;
