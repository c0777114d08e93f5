#!/usr/bin/env bash
# Fine-tunes mms-small on one GPU (`--device wgpu`) within a wall-clock budget, from the shipped
# mms-small-real weights, on the four training sets of experiments/ generated on the spot:
#
#   scripts/train_gpu.sh PINS OUT [SECONDS] [DEVICE]
#
# PINS is a pins binary built with `--features wgpu`; OUT receives the checks (checks.txt: the
# GPU's timings against the CPU's and the flow of the shipped weights on both devices), the
# run's log.csv, curves.png, config.json and its best/last weights. With STEPS set (the shipped
# run: STEPS=900, the config's own count) the run takes that many steps; otherwise the count is
# set from a calibration: 12 steps are timed first, then the run gets as many steps as fit the
# time left, so that its one-cycle schedule ends inside the budget. Without a working GPU it
# stops before training. WORK (default /tmp/pins-gpu) holds the data; COUNT, when set, makes each training
# set that many pairs (a quick try of the script).
set -uo pipefail
PINS=${1:?usage: train_gpu.sh PINS OUT [SECONDS] [DEVICE]}
OUT=${2:?usage: train_gpu.sh PINS OUT [SECONDS] [DEVICE]}
BUDGET=${3:-480}
DEVICE=${4:-wgpu}
WORK=${WORK:-/tmp/pins-gpu}
CONFIG=${CONFIG:-experiments/train_small_gpu.json}
count512=(--count "${COUNT:-800}")
count=()
[ -n "${COUNT:-}" ] && count=(--count "$COUNT")
INIT=datasets/weights/mms-small-real.safetensors
t0=$(date +%s)
elapsed() { echo $(($(date +%s) - t0)); }
mkdir -p "$OUT" "$WORK"
checks="$OUT/checks.txt"
say() { echo "[$(elapsed) s] $*" | tee -a "$checks"; }

# 1. The training data, on the CPU cores, while the GPU is checked.
(
    "$PINS" generate --quiet --config experiments/train_data_real.json "${count[@]}" --out "$WORK/real" &&
        "$PINS" generate --quiet --config experiments/train_data_pins.json "${count[@]}" --out "$WORK/pins" &&
        "$PINS" generate --quiet --config experiments/train_data_sprites.json "${count[@]}" --out "$WORK/sprites" &&
        "$PINS" generate --quiet --config experiments/train_data_512.json "${count512[@]}" --out "$WORK/g512" &&
        touch "$WORK/data.ok"
) >"$WORK/generate.log" 2>&1 &
gen=$!

# 2. The GPU: inference and a training step, timed (the first run compiles the kernels).
say "device $DEVICE"
for mode in infer train; do
    if ! "$PINS" bench-flow --device "$DEVICE" --mode "$mode" --reps 5 >>"$checks" 2>&1; then
        say "bench-flow --mode $mode on $DEVICE failed: no training on it"
        kill "$gen" 2>/dev/null
        exit 2
    fi
done
wait "$gen"
if [ ! -f "$WORK/data.ok" ]; then
    cat "$WORK/generate.log" | tail -20 | tee -a "$checks"
    say "generating the data failed"
    exit 3
fi
say "data generated"
# The CPU's timings on the same machine, now that the generator is done.
for mode in infer train; do
    "$PINS" bench-flow --device cpu --mode "$mode" --reps 3 >>"$checks" 2>&1
done

# 3. The shipped weights on both devices, one real-textured pair: how far apart the flows are.
pair="$WORK/real/00000"
for dev in cpu "$DEVICE"; do
    "$PINS" infer --weights default --img1 "${pair}_img1.png" --img2 "${pair}_img2.png" \
        --out "$WORK/flow_${dev/:/_}.flo" --iters 12 --start zero --refine none --device "$dev" \
        >>"$checks" 2>&1
done
python3 - "$WORK/flow_cpu.flo" "$WORK/flow_${DEVICE/:/_}.flo" "${pair}_flow.flo" <<'PY' 2>&1 | tee -a "$checks"
import sys, numpy as np
def flo(p):
    b = open(p, "rb").read()
    w, h = np.frombuffer(b[4:12], np.int32)
    return np.frombuffer(b[12:], np.float32).reshape(h, w, 2)
c, g, t = (flo(p) for p in sys.argv[1:4])
d = np.linalg.norm(c - g, axis=2)
ok = np.isfinite(t).all(axis=2) & (np.abs(t) < 1e9).all(axis=2)
epe = lambda f: np.linalg.norm(f - t, axis=2)[ok].mean()
print(f"shipped weights, cpu vs gpu: max |d| {d.max():.3g} px, mean {d.mean():.3g} px; "
      f"EPE cpu {epe(c):.4f} gpu {epe(g):.4f}")
PY

# 4. The training set: the four folders interleaved by hard links.
python3 - "$WORK" <<'PY'
import os, sys
w = sys.argv[1]
sets = [(d, len([f for f in os.listdir(f"{w}/{d}") if f.endswith("_flow.flo")]))
        for d in ("real", "pins", "sprites", "g512")]
items = sorted(((i + .5) / n, d, i) for d, n in sets for i in range(n))
os.makedirs(f"{w}/mix", exist_ok=True)
for k, (_, d, i) in enumerate(items):
    for f in ("img1.png", "img2.png", "flow.flo"):
        dst = f"{w}/mix/{k:05d}_{f}"
        if not os.path.exists(dst):
            os.link(f"{w}/{d}/{i:05d}_{f}", dst)
print(len(items), "pairs in", f"{w}/mix")
PY

# 5. The step count: STEPS, or a calibration of 12 timed steps.
if [ -n "${STEPS:-}" ]; then
    steps=$STEPS
else
    rm -rf "$WORK/cal"
    "$PINS" train --quiet --config "$CONFIG" --data "$WORK/mix" --out "$WORK/cal" --init "$INIT" \
        --device "$DEVICE" --stop-after 12 >>"$checks" 2>&1 || { say "calibration failed"; exit 4; }
    steps=$(python3 - "$WORK/cal/log.csv" "$BUDGET" "$(elapsed)" <<'PY'
import csv, sys, statistics
rows = list(csv.DictReader(open(sys.argv[1])))
ms = [float(r["ms_per_step"]) for r in rows]
steady = statistics.median(ms[5:])
startup = sum(ms[:3]) - 3 * steady          # kernel compilation, paid again by the run
left = float(sys.argv[2]) - float(sys.argv[3]) - 30 - startup / 1e3
steps = int(left / (steady / 1e3) * 0.9)    # 10 % for validation and checkpoints
print(max(steps, 0))
PY
)
    say "calibration: $(tail -n +7 "$WORK/cal/log.csv" | cut -d, -f6 | tr '\n' ' ') ms per step; run of $steps steps"
    [ "$steps" -ge 50 ] || { say "too little time left to train"; exit 5; }
fi

# 6. The run, then its weights.
python3 - "$CONFIG" "$steps" "$WORK/config.json" <<'PY'
import json, sys
c = json.load(open(sys.argv[1]))
c["steps"] = int(sys.argv[2])
c["val_every"] = max(50, c["steps"] // 6)
json.dump(c, open(sys.argv[3], "w"), indent=2)
PY
rm -rf "$WORK/run"
timeout $((BUDGET - $(elapsed) - 15)) "$PINS" train --quiet --config "$WORK/config.json" \
    --data "$WORK/mix" --out "$WORK/run" --init "$INIT" --device "$DEVICE" >>"$checks" 2>&1
say "train exited with $?"
cp "$WORK/config.json" "$OUT/config.json"
for f in log.csv curves.png best.safetensors last.safetensors; do
    [ -f "$WORK/run/$f" ] && cp "$WORK/run/$f" "$OUT/$f"
done
tail -3 "$WORK/run/log.csv" | tee -a "$checks"
say "done"
