//! The bridge between Burn's tensors and the host kernels' memory: the CPU backend types
//! (plain and autodiff) and the conversions between a backend primitive, a plain tensor and a
//! host vector, read in place where the tensor is contiguous.

use burn::backend::autodiff::checkpoint::strategy::NoCheckpointing;
use burn::backend::{Autodiff, BackendTypes, Flex};
use burn::prelude::*;

/// The autodiff CPU backend that `Device::flex().autodiff()` tensors live on.
pub type Ad = Autodiff<Flex, NoCheckpointing>;
/// A CPU-backend tensor primitive.
pub type FlexT = <Flex as BackendTypes>::FloatTensorPrimitive;
/// Its autodiff-tracked form.
pub type AdT = <Ad as BackendTypes>::FloatTensorPrimitive;

/// A CPU-backend primitive as a plain (non-autodiff) tensor, without a copy.
pub fn plain<const D: usize>(t: FlexT) -> Tensor<D> {
    Tensor::<D>::from_primitive::<Flex>(t)
}

/// A plain CPU tensor back to its primitive. The host kernels only produce CPU tensors, so a
/// failure is a bug, not bad input.
pub fn primitive<const D: usize>(t: Tensor<D>) -> FlexT {
    match t.try_into_primitive::<Flex>() {
        Ok(p) => p,
        Err(e) => panic!("a host kernel produced a tensor off the CPU backend: {e:?}"),
    }
}

/// The f32 values and shape of a CPU-backend tensor, read in place: borrowed from the tensor's
/// buffer when it is contiguous, copied once into a contiguous buffer otherwise. A tensor of
/// another dtype reads as empty (the operations check f32 before they are built).
pub struct HostView<const D: usize> {
    t: FlexT,
    pub dims: [usize; D],
}

impl<const D: usize> HostView<D> {
    pub fn new(t: FlexT) -> Self {
        let dims = plain::<D>(t.clone()).dims();
        let t = if t.as_slice::<f32>().is_some() {
            t
        } else {
            t.to_contiguous()
        };
        Self { t, dims }
    }

    /// A plain CPU tensor's values; `None` off the CPU backend.
    pub fn of(t: Tensor<D>) -> Option<Self> {
        t.try_into_primitive::<Flex>().ok().map(Self::new)
    }

    pub fn values(&self) -> &[f32] {
        self.t.as_slice::<f32>().unwrap_or(&[])
    }
}

/// Host values as a primitive of the given shape.
pub fn from_host<const D: usize>(v: Vec<f32>, shape: [usize; D]) -> FlexT {
    primitive(Tensor::<D>::from_data(
        TensorData::new(v, shape),
        &Device::flex(),
    ))
}
