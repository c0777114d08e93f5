//! The one choice between the host kernels and Burn's tensor operations: every heavy operation
//! of the network asks [`Route::of`] once, with all its tensor operands, and runs the path it
//! names. Plain f32 tensors on the CPU backend (`Device::flex()`) run the host kernels of
//! [`crate::flow::kernels`] directly; f32 tensors on the autodiff CPU backend
//! (`Device::flex().autodiff()`) run them inside one tracked operation whose `Backward` runs the
//! gradient kernels; anything else (a GPU, another dtype, operands on different devices) keeps
//! Burn's operations, with Burn's own gradients under autodiff.

use burn::backend::Flex;
use burn::prelude::*;
use burn::tensor::DType;

use super::bridge::Ad;
use crate::flow::kernels::par;

/// Which implementation of an operation runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Route {
    /// Host kernels on plain CPU tensors (inference).
    Host,
    /// Host kernels in one tracked operation with its backward pass (training on the CPU).
    HostAutodiff,
    /// Burn's tensor operations (another device or dtype).
    Burn,
    /// Burn's tensor operations and Burn's gradients (training elsewhere).
    BurnAutodiff,
}

/// Where one operand lives, for [`Route::of`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Operand {
    place: Place,
    f32: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Place {
    Flex,
    FlexAutodiff,
    Elsewhere { autodiff: bool },
}

impl Operand {
    pub fn of<const D: usize>(t: &Tensor<D>) -> Self {
        let place = if t.clone().try_into_primitive::<Ad>().is_ok() {
            Place::FlexAutodiff
        } else if t.clone().try_into_primitive::<Flex>().is_ok() {
            Place::Flex
        } else {
            Place::Elsewhere {
                autodiff: t.is_autodiff(),
            }
        };
        Self {
            place,
            f32: t.dtype() == DType::F32,
        }
    }
}

impl Route {
    /// The route of an operation on `operands`: the host kernels when every operand is an f32
    /// tensor on the same CPU backend, Burn otherwise (autodiff when any operand is).
    pub fn of(operands: impl IntoIterator<Item = Operand>) -> Self {
        let operands: Vec<Operand> = operands.into_iter().collect();
        let all = |place: Place| operands.iter().all(|o| o.f32 && o.place == place);
        if operands.is_empty() {
            Route::Burn
        } else if all(Place::Flex) {
            Route::Host
        } else if all(Place::FlexAutodiff) {
            Route::HostAutodiff
        } else if operands.iter().any(|o| {
            matches!(
                o.place,
                Place::FlexAutodiff | Place::Elsewhere { autodiff: true }
            )
        }) {
            Route::BurnAutodiff
        } else {
            Route::Burn
        }
    }

    /// Whether gradients are recorded on this route.
    pub fn is_autodiff(self) -> bool {
        matches!(self, Route::HostAutodiff | Route::BurnAutodiff)
    }
}

/// `(a(), b())` for two independent parts of a forward pass on `on`: side by side on the thread
/// pool at inference, so that small layers that cannot use every core leave the rest to the
/// other part; one after the other under autodiff, where the graph is recorded in order.
pub fn both<A: Send, B: Send>(
    on: &Tensor<4>,
    a: impl FnOnce() -> A + Send,
    b: impl FnOnce() -> B + Send,
) -> (A, B) {
    if on.is_autodiff() {
        (a(), b())
    } else {
        par::join(a, b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn routes_by_backend_autodiff_and_dtype() {
        let flex = Device::flex();
        let ad = flex.clone().autodiff();
        let plain = Tensor::<4>::zeros([1, 1, 2, 2], &flex);
        let tracked = Tensor::<4>::zeros([1, 1, 2, 2], &ad);
        let bias = Tensor::<1>::zeros([1], &flex);
        assert_eq!(
            Route::of([Operand::of(&plain), Operand::of(&bias)]),
            Route::Host
        );
        assert_eq!(Route::of([Operand::of(&tracked)]), Route::HostAutodiff);
        assert!(Route::of([Operand::of(&tracked)]).is_autodiff());
        // A mix of plain and tracked operands is left to Burn.
        assert_eq!(
            Route::of([Operand::of(&tracked), Operand::of(&bias)]),
            Route::BurnAutodiff
        );
        let f64s = plain.clone().cast(DType::F64);
        assert_eq!(Route::of([Operand::of(&f64s)]), Route::Burn);
        assert_eq!(Route::of([]), Route::Burn);
    }
}
