//! The heavy operations of the MMS network, one entry each, each choosing once (through
//! [`route::Route`]) between the host kernels of [`super::kernels`] on the CPU backend and
//! Burn's tensor operations elsewhere, with the autodiff `Backward` of its host form beside it.
//! [`super::model`] calls these and nothing below them.
//!
//! | entry | file |
//! |---|---|
//! | [`conv_layer`], [`conv_stacked`], [`conv2d`]: convolution + bias + activation | [`conv`], [`conv_backward`] |
//! | [`norm()`]: instance and group normalisation | [`norm`](mod@norm) |
//! | [`corr_pyramid`], [`corr_lookup`]: correlation volume, pyramid and window lookup | [`corr`], [`corr_backward`] |
//! | [`convex_upsample`]: convex 8× upsampling | [`upsample`] |
//! | [`conv_gru`]: the ConvGRU's fused forms | [`gru`] |
//! | [`both`]: two independent parts of a forward pass side by side | [`route`] |

pub mod bridge;
pub mod conv;
pub mod conv_backward;
pub mod corr;
pub mod corr_backward;
pub mod gru;
pub mod norm;
pub mod route;
pub mod upsample;

#[cfg(test)]
pub mod testing;

pub use crate::flow::kernels::act::Act;
pub use conv::{bias_or_zeros, conv_layer, conv_stacked, conv2d};
pub use corr::{Pyramid, corr_lookup, corr_pyramid};
pub use gru::{GruGates, conv_gru};
pub use norm::{NormLayer, norm};
pub use route::{Route, both};
pub use upsample::convex_upsample;
