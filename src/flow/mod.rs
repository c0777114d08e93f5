//! Optical flow: the MMS network (Notes S9–S11), its loss, metrics and visualisation.

pub mod loss;
pub mod metrics;
pub mod model;
pub mod viz;
