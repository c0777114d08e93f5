//! Global gradient-norm clipping, as torch's `clip_grad_norm_`: burn 0.22's clipping option is
//! per parameter tensor, which changes the direction of the update; this scales all gradients
//! by one factor so that their joint L2 norm is at most `max_norm`.

use burn::module::{Module, ModuleVisitor, Param};
use burn::optim::GradientsParams;
use burn::prelude::*;

struct SquaredNorm<'a> {
    grads: &'a GradientsParams,
    sum: f64,
    ids: Vec<(burn::module::ParamId, usize)>,
}

impl ModuleVisitor for SquaredNorm<'_> {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        if let Some(g) = self.grads.get::<D>(param.id) {
            let s: f32 = g.powi_scalar(2).sum().into_scalar();
            self.sum += s as f64;
            self.ids.push((param.id, D));
        }
    }
}

struct Scale<'a> {
    grads: &'a mut GradientsParams,
    factor: f32,
}

impl ModuleVisitor for Scale<'_> {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        if let Some(g) = self.grads.remove::<D>(param.id) {
            self.grads
                .register::<D>(param.id, g.mul_scalar(self.factor));
        }
    }
}

/// Clips `grads` of `module` to a global norm of `max_norm`; returns the norm before clipping
/// (NaN or ∞ when a gradient is not finite, in which case nothing is scaled).
pub fn clip_global_norm<M: Module>(module: &M, grads: &mut GradientsParams, max_norm: f64) -> f64 {
    let mut v = SquaredNorm {
        grads,
        sum: 0.0,
        ids: Vec::new(),
    };
    module.visit(&mut v);
    let norm = v.sum.sqrt();
    if norm.is_finite() && norm > max_norm {
        let mut s = Scale {
            grads,
            factor: (max_norm / (norm + 1e-6)) as f32,
        };
        module.visit(&mut s);
    }
    norm
}
