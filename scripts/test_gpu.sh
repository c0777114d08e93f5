#!/usr/bin/env bash
# The GPU tier of the tests: the wgpu backend (`--features wgpu`, Burn's cubecl backend on
# Vulkan) against the CPU path, a forward pass and two training steps to 1e-4
# (tests/wgpu_backend.rs), plus clippy on that feature. Any Vulkan driver runs it: a GPU's, or
# Mesa's software driver lavapipe on a CPU (Debian: apt install libvulkan1 mesa-vulkan-drivers).
# The build of the wgpu stack takes about half an hour on 2 cores the first time, which is why
# this tier is not part of `cargo test --release`.
#
#   scripts/test_gpu.sh            # builds, then runs; a missing Vulkan device is a failure
#   PINS_TEST_WGPU_DEVICE=wgpu:1 scripts/test_gpu.sh
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/pins-target}"
if ! command -v cargo >/dev/null 2>&1; then
    echo "cargo not found: install the Rust toolchain (rustup) first" >&2
    exit 1
fi
if ! ldconfig -p 2>/dev/null | grep -q 'libvulkan\.so\.1'; then
    echo "no Vulkan loader (libvulkan.so.1): install libvulkan1 and a driver (mesa-vulkan-drivers for lavapipe)" >&2
    exit 1
fi
cargo clippy --release --locked --features wgpu --all-targets -- -D warnings
# Mesa's shader cache stays beside the build between runs.
export MESA_SHADER_CACHE_DIR="$CARGO_TARGET_DIR/mesa-shader-cache"
export CUBECL_AUTOTUNE_LEVEL="${CUBECL_AUTOTUNE_LEVEL:-minimal}"
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-$(mktemp -d)}"
PINS_REQUIRE_VULKAN=1 cargo test --release --locked --features wgpu --test wgpu_backend \
    -- --test-threads 1 --nocapture
