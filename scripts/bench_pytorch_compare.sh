#!/usr/bin/env bash
# pins against the same network in PyTorch (python/pins_mms) and its ONNX export run by ONNX
# Runtime, in one run on one machine: inference of one pair at 368x496 and 480x1440, 12 updates,
# mms-small (pins bench-flow: random weights; pins_mms: the shipped weights; the same work),
# the median of REPS runs after a warm-up, each measurement in its own process.
#
#   scripts/bench_pytorch_compare.sh cpu OUTDIR    pins on flex, torch on the CPU, ONNX Runtime's CPU provider
#   scripts/bench_pytorch_compare.sh gpu OUTDIR    pins --device wgpu, torch on cuda, ONNX Runtime's CUDA
#                                                  provider where onnxruntime-gpu is installed
#
# Environment: PINS (a pins binary; a wgpu build for gpu; default: the release build here),
# PYTHON (python3) with torch, numpy, Pillow (and onnx, onnxscript, onnxruntime unless ONNX=0),
# REPS (5). Writes OUTDIR/results.jsonl and OUTDIR/summary.md (ratio = the peer's time / pins',
# above 1 means pins is faster). Run it on an otherwise idle machine.
set -euo pipefail
cd "$(dirname "$0")/.."
die() { echo "bench_pytorch_compare: $*" >&2; exit 1; }
mode=${1:?usage: bench_pytorch_compare.sh cpu|gpu OUTDIR}
out=${2:?usage: bench_pytorch_compare.sh cpu|gpu OUTDIR}
case "$mode" in
    cpu) pins_device=cpu; torch_device=cpu ;;
    gpu) pins_device=${PINS_DEVICE:-wgpu}; torch_device=cuda ;;
    *) die "mode must be cpu or gpu, got $mode" ;;
esac
REPS=${REPS:-5}
[[ "$REPS" =~ ^[1-9][0-9]*$ ]] || die "REPS must be a positive integer, got $REPS"
PYTHON=${PYTHON:-python3}
PINS=${PINS:-${CARGO_TARGET_DIR:-$HOME/.cache/pins-target}/release/pins}
[ -x "$PINS" ] || die "no pins binary at $PINS (cargo build --release, or set PINS)"
"$PYTHON" -c "import torch, numpy, PIL" 2>/dev/null || die "$PYTHON cannot import torch, numpy and Pillow"
onnx=${ONNX:-1}
if [ "$onnx" = 1 ] && ! "$PYTHON" -c "import onnx, onnxscript, onnxruntime" 2>/dev/null; then
    echo "bench_pytorch_compare: no onnx/onnxscript/onnxruntime: ONNX left out" >&2
    onnx=0
fi
mkdir -p "$out"
results="$out/results.jsonl"
: > "$results"
export PYTHONPATH="$PWD/python${PYTHONPATH:+:$PYTHONPATH}"
{
    echo "date: $(date -u +%Y-%m-%dT%H:%M:%SZ)"
    echo "host: $(uname -srm), $(nproc) cores; $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ //')"
    echo "commit: $(git rev-parse --short HEAD 2>/dev/null || echo unknown)"
    echo "torch: $("$PYTHON" -c 'import torch; print(torch.__version__, torch.get_num_threads(), "threads")')"
    echo "mode: $mode (pins --device $pins_device, torch $torch_device), reps $REPS"
} | tee "$out/env.txt"
if [ "$onnx" = 1 ]; then
    "$PYTHON" -m pins_mms export default --out "$out/mms-small-real-12.onnx" > "$out/export.log" 2>&1 ||
        die "the ONNX export failed (see $out/export.log)"
fi
for size in 368x496 480x1440; do
    h=${size%x*}
    w=${size#*x}
    "$PINS" bench-flow --model mms-small --mode infer --height "$h" --width "$w" --iters 12 \
        --reps "$REPS" --device "$pins_device" | tail -n 1 >> "$results"
    "$PYTHON" -m pins_mms bench --height "$h" --width "$w" --iters 12 --reps "$REPS" \
        --device "$torch_device" >> "$results"
    if [ "$onnx" = 1 ]; then
        "$PYTHON" -m pins_mms bench --onnx "$out/mms-small-real-12.onnx" --height "$h" --width "$w" \
            --reps "$REPS" --device "$torch_device" >> "$results"
    fi
done
"$PYTHON" - "$results" <<'PY' | tee "$out/summary.md"
import json, sys
rows = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
print("| size | tool | ms per pair | peer / pins |")
print("|---|---|---|---|")
for size in sorted({(r["height"], r["width"]) for r in rows}):
    here = [r for r in rows if (r["height"], r["width"]) == size]
    pins = next((r["ms"] for r in here if r["tool"].startswith("pins ")), None)
    for r in here:
        ratio = "" if pins is None or r["tool"].startswith("pins ") else f"{r['ms'] / pins:.2f}×"
        print(f"| {size[1]}×{size[0]} | {r['tool']} | {r['ms']:.0f} | {ratio} |")
PY
