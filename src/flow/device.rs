//! Choosing where the network runs: the pure-Rust `flex` CPU backend by default; GPU backends
//! behind cargo features, picked at run time by name, with no change to the model code.

use burn::prelude::*;

use crate::error::{Error, Result};

/// The device named `name`: `cpu` (flex), or `cuda` / `cuda:N` when built with `--features cuda`.
pub fn select(name: &str) -> Result<Device> {
    match name {
        "cpu" | "flex" => Ok(Device::flex()),
        #[cfg(feature = "cuda")]
        n if n == "cuda" || n.starts_with("cuda:") => {
            let index: usize = n
                .strip_prefix("cuda:")
                .map(|i| i.parse())
                .transpose()
                .map_err(|_| Error::invalid("--device", format!("{n:?}: expected cuda:N")))?
                .unwrap_or(0);
            Ok(Device::cuda(index))
        }
        other => Err(Error::invalid(
            "--device",
            format!(
                "{other:?} is not available in this build; use cpu{}",
                if cfg!(feature = "cuda") {
                    " or cuda[:N]"
                } else {
                    " (GPU backends need e.g. `cargo build --features cuda`)"
                }
            ),
        )),
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn cpu_is_always_there_and_unknown_names_are_errors() {
        assert!(super::select("cpu").is_ok());
        let err = super::select("tpu").unwrap_err().to_string();
        assert!(err.contains("tpu"), "{err}");
    }
}
