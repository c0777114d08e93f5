//! What the camera looks at: procedural layered scenes with exact flow, test patterns, readers.

pub mod affine;
pub mod block;
pub mod chairs;
pub mod ground;
pub mod layered;
pub mod movers;
pub mod patterns;
pub mod photos;
pub mod pose;
pub mod readers;
pub mod shape;
pub mod texture;
pub mod trajectory;
pub mod truth;

pub use affine::Affine;
pub use chairs::{ChairsConfig, ChairsDraw, TranslationLaw};
pub use layered::{Fill, Layer, LayeredScene};
pub use movers::MoversConfig;
pub use pose::{Homography, Pose};
pub use shape::Shape;
