#!/usr/bin/env bash
# MMS inference on a GPU against the same machine's CPU cores, one run: `pins bench-flow --mode
# infer` at the tracker's full-size point (640×480, 4 iterations) and at 368×496 with 12
# iterations, on DEVICE with cubecl's autotuning at its default and then at `minimal`, and on
# the CPU. Medians after a warm-up; each line is bench-flow's JSON, preceded by the time since
# the start (the first GPU call pays the kernels' compilation and the autotuning).
#
#   scripts/bench_gpu_infer.sh PINS [DEVICE] [REPS]
#
# PINS is a pins binary built with `--features wgpu` (DEVICE wgpu, the default) or `cuda`.
set -uo pipefail
B=${1:?usage: bench_gpu_infer.sh PINS [DEVICE] [REPS]}
DEVICE=${2:-wgpu}
REPS=${3:-10}
t0=$(date +%s)
run() { echo "# [$(($(date +%s) - t0)) s] $*"; timeout 120 "$@"; }
for level in default minimal; do
    [ "$level" = minimal ] && export CUBECL_AUTOTUNE_LEVEL=minimal
    echo "## $DEVICE, autotune $level"
    run "$B" bench-flow --device "$DEVICE" --mode infer --height 480 --width 640 --iters 4 --reps "$REPS"
    run "$B" bench-flow --device "$DEVICE" --mode infer --reps "$REPS"
done
unset CUBECL_AUTOTUNE_LEVEL
echo "## cpu ($(nproc) cores)"
run "$B" bench-flow --device cpu --mode infer --height 480 --width 640 --iters 4 --reps 5
run "$B" bench-flow --device cpu --mode infer --reps 5
echo "# [$(($(date +%s) - t0)) s] done"
