#!/usr/bin/env bash
# Fine-tunes the tracker's weights (mms-small, stage 3) on one GPU within a wall-clock budget,
# on what the tracker sees: disc clips rendered through the camera (scripts/track_train_data.py,
# scene seeds from 3000, apart from every tracking experiment), mixed with train_data_pins and
# train_data_512 so the network keeps its general flow. Several configs (e.g. two moving weights)
# train side by side on the one GPU:
#
#   scripts/train_gpu_tracker.sh PINS OUT BUDGET_SECONDS CONFIG [CONFIG...]
#
# PINS is a pins binary built with `--features wgpu`. OUT receives checks.txt and, for the i-th
# config, i_log.csv, i_best.safetensors and i_last.safetensors. While the data is generated on
# the CPU cores, the configs run 12 steps side by side on a small set (this compiles the GPU
# kernels and times a step); each run then gets the step count that fits the time left, so its
# one-cycle schedule ends inside the budget. Environment: DEVICE (wgpu), WORK (/tmp/pins-tracker),
# CLIPS (48) and FRAMES (30) of the disc clips, JOBS (8) clip renders at a time, PINS_COUNT (400)
# and G512_COUNT (600) pairs of the two generator sets, INIT (the stage-3 weights), STEPS (a
# fixed step count instead of the calibrated one).
set -uo pipefail
usage="usage: train_gpu_tracker.sh PINS OUT BUDGET_SECONDS CONFIG [CONFIG...]"
PINS=${1:?$usage}
OUT=${2:?$usage}
BUDGET=${3:?$usage}
shift 3
[ $# -ge 1 ] || { echo "$usage" >&2; exit 1; }
CONFIGS=("$@")
DEVICE=${DEVICE:-wgpu}
WORK=${WORK:-/tmp/pins-tracker}
CLIPS=${CLIPS:-48}
FRAMES=${FRAMES:-30}
JOBS=${JOBS:-8}
INIT=${INIT:-datasets/weights/mms-small.safetensors}
t0=$(date +%s)
elapsed() { echo $(($(date +%s) - t0)); }
mkdir -p "$OUT" "$WORK"
checks="$OUT/checks.txt"
say() { echo "[$(elapsed) s] $*" | tee -a "$checks"; }
for c in "${CONFIGS[@]}"; do
    [ -f "$c" ] || { say "no config $c"; exit 1; }
done

# 1. The data, on the CPU cores: the disc clips in JOBS shares, and the two generator sets.
rm -rf "$WORK"/discs* "$WORK/pins" "$WORK/g512" "$WORK/warm" "$WORK/mix" "$WORK"/cal* "$WORK"/run*
per=$(((CLIPS + JOBS - 1) / JOBS))
pids=()
for ((j = 0; j < JOBS; j++)); do
    python3 scripts/track_train_data.py --pins "$PINS" --out "$WORK/discs$j" --clips "$per" \
        --frames "$FRAMES" --seed $((3000 + j * per)) >"$WORK/discs$j.log" 2>&1 &
    pids+=($!)
done
(
    "$PINS" generate --quiet --config experiments/train_data_pins.json --count "${PINS_COUNT:-400}" \
        --out "$WORK/pins" &&
        "$PINS" generate --quiet --config experiments/train_data_512.json \
            --count "${G512_COUNT:-600}" --out "$WORK/g512"
) >"$WORK/generate.log" 2>&1 &
pids+=($!)

# 2. Meanwhile the GPU: every config 12 steps side by side on a small set (kernel compilation
# and the step's time when the runs share the GPU).
"$PINS" generate --quiet --config experiments/train_data_512.json --count 32 --out "$WORK/warm" \
    >>"$checks" 2>&1 || { say "generating the warm-up set failed"; exit 2; }
say "device $DEVICE; calibrating ${#CONFIGS[@]} configs side by side"
cal=()
for i in "${!CONFIGS[@]}"; do
    "$PINS" train --quiet --config "${CONFIGS[$i]}" --data "$WORK/warm" --out "$WORK/cal$i" \
        --init "$INIT" --device "$DEVICE" --stop-after 12 >>"$checks" 2>&1 &
    cal+=($!)
done
for p in "${cal[@]}"; do
    wait "$p" || { say "calibration on $DEVICE failed: no training on it"; kill "${pids[@]}" 2>/dev/null; exit 3; }
done
say "calibrated"
for p in "${pids[@]}"; do
    wait "$p" || { tail -5 "$WORK"/*.log | tee -a "$checks"; say "generating the data failed"; exit 4; }
done
say "data generated: $(cat "$WORK"/discs*.log | tr '\n' ' ')"

# 3. The training set: the folders interleaved by hard links.
python3 - "$WORK" <<'PY' | tee -a "$checks"
import os, sys
w = sys.argv[1]
dirs = sorted(d for d in os.listdir(w) if d.startswith("discs") and os.path.isdir(f"{w}/{d}")
              and not d.endswith(".clips")) + ["pins", "g512"]
sets = [(d, len([f for f in os.listdir(f"{w}/{d}") if f.endswith("_flow.flo")])) for d in dirs]
items = sorted(((i + .5) / n, d, i) for d, n in sets for i in range(n))
os.makedirs(f"{w}/mix")
for k, (_, d, i) in enumerate(items):
    for f in ("img1.png", "img2.png", "flow.flo"):
        os.link(f"{w}/{d}/{i:05d}_{f}", f"{w}/mix/{k:05d}_{f}")
print(len(items), "pairs in", f"{w}/mix:", ", ".join(f"{d} {n}" for d, n in sets))
PY

# 4. The step count: STEPS, or what fits the time left at the calibrated pace.
if [ -n "${STEPS:-}" ]; then
    steps=$STEPS
else
    steps=$(python3 - "$BUDGET" "$(elapsed)" "$WORK"/cal*/log.csv <<'PY'
import csv, sys, statistics
budget, now = float(sys.argv[1]), float(sys.argv[2])
paces = []
for p in sys.argv[3:]:
    ms = [float(r["ms_per_step"]) for r in csv.DictReader(open(p))]
    paces.append(statistics.median(ms[5:]))
left = budget - now - 45                       # the runs' start, last checkpoint, copying
print(max(int(left / (max(paces) / 1e3) * 0.88), 0))   # 12 % for validation and checkpoints
PY
)
fi
say "runs of $steps steps (steady ms per step when side by side: $(for i in "${!CONFIGS[@]}"; do tail -n +7 "$WORK/cal$i/log.csv" | cut -d, -f6 | sort -n | sed -n 3p; done | tr '\n' ' '))"
[ "$steps" -ge 50 ] || { say "too little time left to train"; exit 5; }

# 5. The runs, side by side.
runs=()
for i in "${!CONFIGS[@]}"; do
    python3 - "${CONFIGS[$i]}" "$steps" "$WORK/config$i.json" <<'PY'
import json, sys
c = json.load(open(sys.argv[1]))
c["steps"] = int(sys.argv[2])
c["val_every"] = max(50, c["steps"] // 4)
c["checkpoint_every"] = max(25, c["steps"] // 10)
json.dump(c, open(sys.argv[3], "w"), indent=2)
PY
    timeout $((BUDGET - $(elapsed) - 10)) "$PINS" train --quiet --config "$WORK/config$i.json" \
        --data "$WORK/mix" --out "$WORK/run$i" --init "$INIT" --device "$DEVICE" \
        >"$WORK/run$i.log" 2>&1 &
    runs+=($!)
done
for i in "${!runs[@]}"; do
    wait "${runs[$i]}"
    say "run $i (${CONFIGS[$i]}) exited with $?: $(tail -1 "$WORK/run$i.log")"
    for f in log.csv best.safetensors last.safetensors; do
        [ -f "$WORK/run$i/$f" ] && cp "$WORK/run$i/$f" "$OUT/${i}_$f"
    done
    tail -2 "$WORK/run$i/log.csv" >>"$checks"
done
say "done"
