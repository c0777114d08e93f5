//! Core data types shared by every layer: planar images and flow fields.

mod flow;
mod image;

pub use flow::Flow;
pub use image::Image;
