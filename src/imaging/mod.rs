//! The camera model (Notes S4–S5, Eqs. S1–S4): a pipeline of stages built from a config.

pub mod box_filter;
pub mod calibrate;
pub mod config;
pub mod convolve;
pub mod fft2;
pub mod noise;
pub mod pipeline;
pub mod psf_source;
pub mod resize;
pub mod similarity;
pub mod tone;
pub mod tone_lut;

pub use config::CameraConfig;
pub use convolve::ConvMethod;
pub use noise::{NoiseConfig, NoiseModel};
pub use pipeline::{Camera, Stage};
