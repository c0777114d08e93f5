//! The activation after a layer (Note S9: ReLU in the encoders and heads, σ and tanh in the
//! ConvGRU of Eqs. S9–S12), applied inside the host convolution: forward on host values and its
//! derivative read from the output for the backward pass.

use super::par::{map, zip_map};
use super::vexp::exp;

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
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flow::kernels::testing::{Tol, assert_close};

    /// Each derivative read from the output equals a central difference of the forward pass.
    #[test]
    fn derivatives_from_the_output_match_finite_differences() {
        let xs: Vec<f32> = (0..41).map(|i| -4.0 + 0.2 * i as f32 + 0.013).collect();
        for act in [Act::Identity, Act::Relu, Act::Sigmoid, Act::Tanh] {
            let mut y = xs.clone();
            act.apply(&mut y);
            let ones = vec![1f32; xs.len()];
            let got = act.backward(&y, &ones);
            let h = 1e-2f32;
            let want: Vec<f32> = xs
                .iter()
                .map(|&x| {
                    let (mut a, mut b) = ([x + h], [x - h]);
                    act.apply(&mut a);
                    act.apply(&mut b);
                    (a[0] - b[0]) / (2.0 * h)
                })
                .collect();
            assert_close(&got, &want, Tol::Abs(1e-3), &format!("{act:?}′"));
        }
    }
}
