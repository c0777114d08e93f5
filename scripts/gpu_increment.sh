#!/usr/bin/env bash
# One GPU lease's work in one command: the live system's benchmark on the GPU
# (experiments/bench_live_gpu.json), then the campaign's training (scripts/train_campaign.sh gpu,
# its pairs made on the host's cores as it trains) for what is left of SECONDS.
#
#   scripts/gpu_increment.sh PINS OUTDIR SECONDS [DEVICE]
#
# PINS is a pins binary built with `--features wgpu` (DEVICE wgpu, the default) or `cuda`.
# OUTDIR receives log.txt (this script's output, the status included),
# bench_live.md, and the training's state.json, model-*.bpk, optim-*.bin, log.csv,
# last.safetensors and average.safetensors (the mean of the session's snapshots) in
# OUTDIR/train (continue here with CHECKPOINT=OUTDIR/train scripts/train_campaign.sh), and with
# COOLDOWN_MINUTES=M in the environment, cooldown.safetensors and cooldown_log.csv: a branch of
# the run cooled down in the session's last M minutes.
# The training starts where train_campaign.sh says (a checkpoint in WORK, else the campaign's
# committed weights). Ends within SECONDS of its start, whatever the benchmark does.
set -uo pipefail
cd "$(dirname "$0")/.."
PINS=${1:?usage: gpu_increment.sh PINS OUTDIR SECONDS [DEVICE]}
OUTDIR=${2:?usage: gpu_increment.sh PINS OUTDIR SECONDS [DEVICE]}
SECONDS_TOTAL=${3:?usage: gpu_increment.sh PINS OUTDIR SECONDS [DEVICE]}
DEVICE=${4:-wgpu}
export WORK=${WORK:-/tmp/campaign}
t0=$(date +%s)
mkdir -p "$OUTDIR/train"
exec > >(tee "$OUTDIR/log.txt") 2>&1
say() { echo "[$(($(date +%s) - t0)) s] $*"; }
say "gpu_increment: $DEVICE, $(nproc) cores, $SECONDS_TOTAL s"
nvidia-smi -L 2>/dev/null || true

# The live benchmark on the GPU, bounded so that the training keeps most of the lease.
bench_s=$((SECONDS_TOTAL / 3))
say "bench-live on $DEVICE (at most $bench_s s)"
CUBECL_AUTOTUNE_LEVEL=minimal timeout "$bench_s" "$PINS" bench-live --device "$DEVICE" \
    --config experiments/bench_live_gpu.json --out "$WORK.bench_live" &&
    cp "$WORK.bench_live/report.md" "$OUTDIR/bench_live.md"
say "bench-live exited"

# The training: whole minutes of what is left, less a minute for its last step and the copies.
minutes=$(((SECONDS_TOTAL - ($(date +%s) - t0) - 60) / 60))
[ "$minutes" -gt 9 ] && minutes=9
cool=${COOLDOWN_MINUTES:-0}
if [ "$minutes" -ge 1 ] && [[ "$cool" =~ ^[0-9]+$ ]] && [ "$((10#$cool))" -ge "$minutes" ]; then
    say "no time to cool down ($cool of $minutes min): training alone"
    cool=0
fi
if [ "$minutes" -ge 1 ]; then
    say "training for $minutes min"
    PINS="$PINS" DEVICE="$DEVICE" COOLDOWN_MINUTES="$cool" \
        scripts/train_campaign.sh gpu "$minutes" "$OUTDIR/train"
    rm -f "$OUTDIR/train/best.safetensors" "$OUTDIR/train/status.txt"
else
    say "no time left to train"
fi
say "done"
