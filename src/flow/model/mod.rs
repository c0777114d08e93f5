//! The MMS network (Notes S9–S11) in Burn, as the paper and RAFT read it: every heavy operation
//! is one call into [`super::ops`].
//!
//! | file | what |
//! |---|---|
//! | [`mms`] | the network: encoders, correlation, `iters` refinements, upsampling |
//! | [`encoder`] | DSMSCE: stem, residual stages, pyramid pooling (Eq. S13), DASPP (Eqs. S14–S15) |
//! | [`blocks`] | padded convolutions, the normalisation switch, the residual block |
//! | [`corr`] | the correlation pyramid and its window lookup |
//! | [`update`] | motion encoder, flow head, mask head |
//! | [`gru`] | the ConvGRU, Eqs. S9–S12 |
//! | [`upsample`] | convex 8× upsampling |
//! | [`padder`] | padding any image size to a multiple of 8 and back |
//! | [`config`] | the sizes: `mms`, `mms-small` |

pub mod blocks;
pub mod config;
pub mod corr;
pub mod encoder;
pub mod gru;
pub mod mms;
pub mod padder;
pub mod update;
pub mod upsample;

pub use config::{MmsConfig, NormKind};
pub use mms::Mms;
pub use padder::InputPadder;
