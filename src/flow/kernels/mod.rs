//! The host kernels of the MMS network on the CPU: plain `&[f32]` mathematics on row-major
//! buffers, no Burn types. `unsafe`, `gemm` and `rayon` live here and nowhere else in
//! `flow`. [`super::ops`] decides when they run and wraps them as tensor operations.
//!
//! | file | what |
//! |---|---|
//! | [`conv`] | the convolution `W ⋆ x + b` and its gradients (∂x by the transposed kernel, ∂W, ∂b) |
//! | [`geometry`] | sizes of one convolution, its parameters, the parallel loop over row bands |
//! | [`unfold`] | convolution by channel-first unfolding (im2col) and one product per band |
//! | [`shifted`] | stride-1 convolution by one product per tap on a padded input |
//! | [`act`] | ReLU, σ and tanh after a layer, and their derivatives from the output |
//! | [`norm`] | instance and group normalisation and their gradients |
//! | [`corr`] | the all-pairs correlation volume and its pooled pyramid |
//! | [`lookup`] | the bilinear (2r+1)² window lookup and its gradient |
//! | [`upsample`] | convex 8× upsampling and its gradients |
//! | [`vexp`] | a vectorisable `exp` |
//! | [`par`] | the thread pool: `join` and chunked element-wise maps |
//! | [`peak`] | one square matrix product: the machine's rate to measure the layers against |

pub mod act;
pub mod conv;
pub mod corr;
pub mod geometry;
pub mod lookup;
pub mod norm;
pub mod par;
pub mod peak;
pub mod shifted;
pub mod unfold;
pub mod upsample;
pub mod vexp;

#[cfg(test)]
pub mod testing;
