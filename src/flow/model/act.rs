//! The activation after a layer (Note S9: ReLU in the encoders and heads, σ and tanh in the
//! ConvGRU of Eqs. S9–S12), applied inside the host convolution: forward on host values, its
//! derivative from the output for the backward pass, and burn's form for other devices.

use burn::prelude::*;
use burn::tensor::activation::{relu, sigmoid, tanh};

/// The activation that follows a convolution, applied inside the same operation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Act {
    Identity,
    Relu,
    Sigmoid,
    Tanh,
}

impl Act {
    /// In place on host values.
    pub fn apply(self, y: &mut [f32]) {
        match self {
            Act::Identity => {}
            Act::Relu => y.iter_mut().for_each(|v| *v = v.max(0.0)),
            Act::Sigmoid => y.iter_mut().for_each(|v| *v = 1.0 / (1.0 + (-*v).exp())),
            Act::Tanh => y.iter_mut().for_each(|v| *v = v.tanh()),
        }
    }

    /// `g · act′`, with the derivative read from the activation's output `y`.
    pub fn backward(self, y: &[f32], g: &[f32]) -> Vec<f32> {
        let each = |d: fn(f32, f32) -> f32| y.iter().zip(g).map(|(&y, &g)| d(y, g)).collect();
        match self {
            Act::Identity => g.to_vec(),
            Act::Relu => each(|y, g| if y > 0.0 { g } else { 0.0 }),
            Act::Sigmoid => each(|y, g| g * y * (1.0 - y)),
            Act::Tanh => each(|y, g| g * (1.0 - y * y)),
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
