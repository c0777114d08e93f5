//! Choosing where the network runs: the pure-Rust `flex` CPU backend by default; GPU backends
//! behind cargo features, picked at run time by name, with no change to the model code.
//!
//! `wgpu` (feature `wgpu`) is Burn's cubecl backend on Vulkan, pinned to that API so that a
//! machine without a Vulkan device gets a clear error instead of another API's quirks. It builds
//! offline and runs on any Vulkan driver: an NVIDIA, AMD or Intel GPU, or Mesa's software driver
//! (lavapipe) on a plain CPU, which is how the test suite checks it against the CPU path.

use burn::prelude::*;

use crate::error::{Error, Result};

/// The names [`select`] accepts in this build, for messages.
pub fn available() -> &'static str {
    if cfg!(all(feature = "cuda", feature = "wgpu")) {
        "cpu, wgpu, wgpu:N, wgpu:cpu, cuda or cuda:N"
    } else if cfg!(feature = "wgpu") {
        "cpu, wgpu, wgpu:N or wgpu:cpu"
    } else if cfg!(feature = "cuda") {
        "cpu, cuda or cuda:N"
    } else {
        "cpu (GPU backends need a build with `--features wgpu` or `--features cuda`)"
    }
}

/// The device named `name`: `cpu` (flex); `wgpu` (the best Vulkan adapter), `wgpu:N` (the N-th
/// discrete GPU) or `wgpu:cpu` (a software Vulkan driver such as lavapipe) in a build with
/// `--features wgpu`; `cuda` / `cuda:N` in a build with `--features cuda`.
pub fn select(name: &str) -> Result<Device> {
    match name {
        "cpu" | "flex" => Ok(Device::flex()),
        #[cfg(feature = "wgpu")]
        n if n == "wgpu" || n.starts_with("wgpu:") => wgpu::select(n),
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
                "{other:?} is not available in this build; use {}",
                available()
            ),
        )),
    }
}

#[cfg(feature = "wgpu")]
mod wgpu {
    use std::collections::HashMap;
    use std::sync::{Mutex, OnceLock};

    use burn::prelude::*;
    use burn::tensor::DeviceKind;
    use burn::tensor::wgpu::WgpuBackend;

    use crate::error::{Error, Result};

    /// A wgpu runtime is initialised once per adapter; later requests reuse its device.
    fn registry() -> &'static Mutex<HashMap<String, Device>> {
        static DEVICES: OnceLock<Mutex<HashMap<String, Device>>> = OnceLock::new();
        DEVICES.get_or_init(|| Mutex::new(HashMap::new()))
    }

    fn kind(name: &str) -> Result<DeviceKind> {
        match name.strip_prefix("wgpu:") {
            None => Ok(DeviceKind::DefaultDevice),
            Some("cpu") => Ok(DeviceKind::Cpu),
            Some(i) => i.parse().map(DeviceKind::DiscreteGpu).map_err(|_| {
                Error::invalid(
                    "--device",
                    format!("{name:?}: expected wgpu, wgpu:N (the N-th discrete GPU) or wgpu:cpu"),
                )
            }),
        }
    }

    pub fn select(name: &str) -> Result<Device> {
        let kind = kind(name)?;
        let mut devices = registry()
            .lock()
            .map_err(|_| Error::invalid("--device", "the wgpu device registry is poisoned"))?;
        if let Some(d) = devices.get(name) {
            return Ok(d.clone());
        }
        let device = Device::wgpu_options()
            .device_kind(kind)
            .graphics_api(WgpuBackend::Vulkan)
            .init()
            .map_err(|e| {
                Error::invalid(
                    "--device",
                    format!(
                        "{name}: no Vulkan device could be opened ({e}); install a Vulkan \
                         driver (on Debian, `mesa-vulkan-drivers` gives the software driver \
                         lavapipe) or use --device cpu"
                    ),
                )
            })?;
        devices.insert(name.to_string(), device.clone());
        Ok(device)
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn cpu_is_always_there_and_unknown_names_are_errors() {
        assert!(super::select("cpu").is_ok());
        let err = super::select("tpu").unwrap_err().to_string();
        assert!(err.contains("tpu"), "{err}");
        assert!(err.contains("cpu"), "{err}");
    }

    #[cfg(feature = "wgpu")]
    #[test]
    fn malformed_wgpu_names_are_errors_before_any_adapter_is_opened() {
        let err = super::select("wgpu:first").unwrap_err().to_string();
        assert!(err.contains("wgpu:N"), "{err}");
    }
}
