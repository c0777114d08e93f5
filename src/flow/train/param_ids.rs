//! Parameter ids that depend on the parameter's place in the network, not on the process: the
//! ids are written into checkpoints (model record and optimiser state), so random ids would
//! make two identical runs write different files.

use burn::module::{Module, ModuleMapper, Param, ParamId};
use burn::prelude::*;

/// `module` with every parameter's id set to a hash (FNV-1a, 64 bit) of its path, e.g.
/// `update.gru.convz.weight`. Call it on a freshly built network, before any optimiser step.
pub fn ids_from_paths<M: Module>(module: M) -> M {
    struct ByPath {
        path: Vec<String>,
    }
    impl ByPath {
        fn id(&self) -> ParamId {
            let mut h: u64 = 0xcbf2_9ce4_8422_2325;
            for b in self.path.join(".").bytes() {
                h ^= u64::from(b);
                h = h.wrapping_mul(0x0000_0100_0000_01b3);
            }
            ParamId::from(h)
        }
    }
    impl ModuleMapper for ByPath {
        fn enter_module(&mut self, name: &str, _container_type: &str) {
            self.path.push(name.to_string());
        }
        fn exit_module(&mut self, _name: &str, _container_type: &str) {
            self.path.pop();
        }
        fn map_float<const D: usize>(&mut self, mut param: Param<Tensor<D>>) -> Param<Tensor<D>> {
            param.id = self.id();
            param
        }
    }
    module.map(&mut ByPath { path: Vec::new() })
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::module::ModuleVisitor;

    fn ids(m: &crate::flow::model::Mms) -> Vec<u64> {
        struct Ids(Vec<u64>);
        impl ModuleVisitor for Ids {
            fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
                self.0.push(p.id.val());
            }
        }
        let mut v = Ids(Vec::new());
        m.visit(&mut v);
        v.0
    }

    #[test]
    fn ids_are_unique_and_the_same_for_every_build() {
        let cfg = crate::flow::model::MmsConfig::named("mms-small").unwrap();
        let dev = Device::flex();
        let a = ids(&ids_from_paths(crate::flow::model::Mms::new(&cfg, &dev)));
        let b = ids(&ids_from_paths(crate::flow::model::Mms::new(&cfg, &dev)));
        assert_eq!(a, b);
        let mut sorted = a.clone();
        sorted.sort();
        sorted.dedup();
        assert_eq!(sorted.len(), a.len(), "one id per parameter");
        assert_ne!(ids(&crate::flow::model::Mms::new(&cfg, &dev)), a);
    }
}
