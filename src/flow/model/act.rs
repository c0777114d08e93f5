//! The activation after a layer (Note S9: ReLU in the encoders and heads, σ and tanh in the
//! ConvGRU of Eqs. S9–S12), applied inside the host convolution: forward on host values, its
//! derivative from the output for the backward pass, and burn's form for other devices.

use burn::prelude::*;
use burn::tensor::activation::{relu, sigmoid, tanh};
use rayon::prelude::*;

use super::vexp::exp;

/// Values per parallel task of the host loops: a layer's output is up to 2²¹ values (the
/// encoders' first stage), the update block's a few 10⁴.
const CHUNK: usize = 1 << 14;

/// The activation that follows a convolution, applied inside the same operation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Act {
    Identity,
    Relu,
    Sigmoid,
    Tanh,
}

impl Act {
    /// In place on host values, in parallel chunks.
    pub fn apply(self, y: &mut [f32]) {
        match self {
            Act::Identity => {}
            Act::Relu => map(y, |v| v.max(0.0)),
            Act::Sigmoid => map(y, |v| 1.0 / (1.0 + exp(-v))),
            Act::Tanh => map(y, f32::tanh),
        }
    }

    /// `g · act′`, with the derivative read from the activation's output `y`.
    pub fn backward(self, y: &[f32], g: &[f32]) -> Vec<f32> {
        match self {
            Act::Identity => g.to_vec(),
            Act::Relu => zip_map(y, g, |y, g| if y > 0.0 { g } else { 0.0 }),
            Act::Sigmoid => zip_map(y, g, |y, g| g * y * (1.0 - y)),
            Act::Tanh => zip_map(y, g, |y, g| g * (1.0 - y * y)),
        }
    }

    /// On a tensor, with burn's activations (any device, differentiable).
    pub fn apply_tensor(self, t: Tensor<4>) -> Tensor<4> {
        match self {
            Act::Identity => t,
            Act::Relu => relu(t),
            Act::Sigmoid => sigmoid(t),
            Act::Tanh => tanh(t),
        }
    }
}

/// `y ← f(y)`, in parallel chunks.
fn map(y: &mut [f32], f: impl Fn(f32) -> f32 + Sync) {
    y.par_chunks_mut(CHUNK)
        .for_each(|c| c.iter_mut().for_each(|v| *v = f(*v)));
}

/// `f(y, g)` elementwise, in parallel chunks.
fn zip_map(y: &[f32], g: &[f32], f: impl Fn(f32, f32) -> f32 + Sync) -> Vec<f32> {
    let mut out = vec![0f32; g.len()];
    out.par_chunks_mut(CHUNK)
        .zip(y.par_chunks(CHUNK).zip(g.par_chunks(CHUNK)))
        .for_each(|(o, (y, g))| {
            for ((o, &y), &g) in o.iter_mut().zip(y).zip(g) {
                *o = f(y, g);
            }
        });
    out
}
