//! The ConvGRU of the update block (Note S9, Eqs. S9–S12): the hidden state h is refined from
//! the input x (context and motion features) by three 3×3 convolutions of the concatenation
//! [h, x], as in RAFT's `ConvGRU`.

use burn::nn::conv::Conv2d;
use burn::prelude::*;

use super::blocks::conv;
use crate::flow::ops::{self, Act, conv_layer};

/// ConvGRU, Eqs. S9–S12, with `Ch` hidden and `Cx` input channels.
#[derive(Module, Debug)]
pub struct ConvGru {
    convz: Conv2d,
    convr: Conv2d,
    convq: Conv2d,
}

impl ConvGru {
    pub fn new(hidden: usize, input: usize, device: &Device) -> Self {
        Self {
            convz: conv(hidden + input, hidden, 3, 1, 1, device),
            convr: conv(hidden + input, hidden, 3, 1, 1, device),
            convq: conv(hidden + input, hidden, 3, 1, 1, device),
        }
    }

    /// One step, `h' = ConvGRU(h, x)`: [`Self::equations`], computed in the fused forms of
    /// [`ops::conv_gru`] (the same numbers).
    ///
    /// # Shapes
    /// `h`: `[B, Ch, H, W]`, `x`: `[B, Cx, H, W]` → `[B, Ch, H, W]`
    pub fn forward(&self, h: Tensor<4>, x: Tensor<4>) -> Tensor<4> {
        ops::conv_gru(h, x, [&self.convz, &self.convr, &self.convq])
    }

    /// Eqs. S9–S12 term by term:
    ///
    /// - S9: z = σ(Conv_z([h, x])), the update gate;
    /// - S10: r = σ(Conv_r([h, x])), the reset gate;
    /// - S11: h̃ = tanh(Conv_q([r ⊙ h, x])), the candidate state;
    /// - S12: h' = (1 − z) ⊙ h + z ⊙ h̃.
    ///
    /// # Shapes
    /// `h`: `[B, Ch, H, W]`, `x`: `[B, Cx, H, W]` → `[B, Ch, H, W]`
    pub fn equations(&self, h: Tensor<4>, x: Tensor<4>) -> Tensor<4> {
        let hx = Tensor::cat(vec![h.clone(), x.clone()], 1); // [B, Ch + Cx, H, W]
        let z = conv_layer(&self.convz, hx.clone(), Act::Sigmoid); // Eq. S9
        let r = conv_layer(&self.convr, hx, Act::Sigmoid); // Eq. S10
        let rh_x = Tensor::cat(vec![r * h.clone(), x], 1);
        let q = conv_layer(&self.convq, rh_x, Act::Tanh); // Eq. S11
        (z.clone().neg() + 1.0) * h + z * q // Eq. S12
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flow::kernels::testing::{Tol, cases};
    use crate::flow::ops::testing::{assert_tensors_close, random};

    /// The fused forms (split kernels at inference, stacked z and r in training) equal
    /// Eqs. S9–S12 as written, values and, in training, the gradients of h, x and the kernels.
    #[test]
    fn fused_forms_match_the_equations() {
        for dev in [Device::flex(), Device::flex().autodiff()] {
            let mut r = cases("gru", dev.is_autodiff() as u64);
            let gru = ConvGru::new(8, 5, &dev);
            let track = |t: Tensor<4>| {
                if dev.is_autodiff() {
                    t.require_grad()
                } else {
                    t
                }
            };
            let h = track(random(&mut r, [2, 8, 6, 7], 1.0, &dev));
            let x = track(random(&mut r, [2, 5, 6, 7], 1.0, &dev));
            let got = gru.forward(h.clone(), x.clone());
            let want = gru.equations(h.clone(), x.clone());
            assert_tensors_close(got.clone(), want.clone(), Tol::Abs(1e-5), "h'");
            if !dev.is_autodiff() {
                continue;
            }
            let weights = random(&mut r, [2, 8, 6, 7], 1.0, &dev);
            let ga = (got * weights.clone()).sum().backward();
            let gb = (want * weights).sum().backward();
            for (t, what) in [(&h, "∂h"), (&x, "∂x")] {
                let (a, b) = (
                    t.grad(&ga).expect("gradient"),
                    t.grad(&gb).expect("gradient"),
                );
                assert_tensors_close(a, b, Tol::Abs(1e-4), what);
            }
            for c in [&gru.convz, &gru.convr, &gru.convq] {
                let w = c.weight.val();
                let (a, b) = (
                    w.grad(&ga).expect("gradient"),
                    w.grad(&gb).expect("gradient"),
                );
                assert_tensors_close(a, b, Tol::Scaled(1e-4), "∂W");
            }
        }
    }
}
