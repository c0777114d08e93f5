#!/usr/bin/env bash
# One run, one machine: the pins flow networks (mms, mms-small) against torchvision's RAFT
# (raft_large, raft_small; random weights) on CPU — time and peak memory of
#   inference of one pair at 368x496 and at 480x1440 (12 flow updates), and
#   one training step, batch 2 at 128x128 (12 updates, sequence loss, AdamW).
# Every measurement runs in its own process, so each peak RSS belongs to one measurement.
# Lines are collected in out/bench_flow/results.jsonl; then a markdown table and the ratios
# (mms vs raft_large, mms-small vs raft_small; >1 means pins is faster / smaller) are printed
# and also written to out/bench_flow/summary.md; each process's stderr goes to the terminal and
# to out/bench_flow/stderr.log, the machine/commit/torch versions to out/bench_flow/env.txt.
#
# Usage: bash scripts/bench_flow_compare.sh            (from anywhere; runs from the repo root)
# Environment:
#   REPS_INFER (3), REPS_TRAIN (5)   timed repetitions per measurement (median reported)
#   PINS       the pins binary; default ${CARGO_TARGET_DIR:-$HOME/.cache/pins-target}/release/pins,
#              built first with `cargo build --release --quiet` (not built when PINS is given)
#   PYTHON     (python3) with torch and torchvision installed (pip install torch torchvision)
# Run it on an otherwise idle machine: both sides use 2 threads (RAYON_NUM_THREADS=2 for pins,
# torch.set_num_threads(2) for RAFT).
set -euo pipefail
cd "$(dirname "$0")/.."

export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/pins-target}"
REPS_INFER="${REPS_INFER:-3}"
REPS_TRAIN="${REPS_TRAIN:-5}"
PYTHON="${PYTHON:-python3}"
out="out/bench_flow"
results="$out/results.jsonl"

die() { echo "bench_flow_compare: error: $*" >&2; exit 1; }

for v in REPS_INFER REPS_TRAIN; do
    [[ "${!v}" =~ ^[1-9][0-9]*$ ]] || die "$v must be a positive integer, got '${!v}'"
done
command -v "$PYTHON" >/dev/null || die "$PYTHON not found"
"$PYTHON" -c "import torch, torchvision" 2>/dev/null \
    || die "$PYTHON cannot import torch and torchvision (pip install torch torchvision)"

if [[ -z "${PINS:-}" ]]; then
    PINS="$CARGO_TARGET_DIR/release/pins"
    echo "building pins (cargo build --release) ..." >&2
    cargo build --release --quiet || die "cargo build --release failed"
fi
[[ -x "$PINS" ]] || die "pins binary not found or not executable: $PINS"

mkdir -p "$out"
: > "$results"
: > "$out/stderr.log"
{
    echo "date: $(date -u +%Y-%m-%dT%H:%M:%SZ)"
    echo "host: $(uname -srm), $(nproc) cores"
    echo "cpu: $(grep -m1 'model name' /proc/cpuinfo 2>/dev/null | cut -d: -f2- | sed 's/^ //' || true)"
    echo "commit: $(git rev-parse --short HEAD 2>/dev/null || echo unknown)"
    echo "torch: $("$PYTHON" -c 'import torch, torchvision; print(torch.__version__, "/ torchvision", torchvision.__version__)')"
    echo "reps: infer $REPS_INFER, train $REPS_TRAIN"
} > "$out/env.txt"
cat "$out/env.txt" >&2

# measure CMD...: runs one measurement in its own process and appends its JSON line.
measure() {
    local tmp line
    tmp="$(mktemp)"
    echo "== $*" >&2
    echo "== $*" >> "$out/stderr.log"
    if ! "$@" > "$tmp" 2> >(tee -a "$out/stderr.log" >&2); then
        cat "$tmp" >&2
        rm -f "$tmp"
        die "measurement failed: $*"
    fi
    line="$(grep '^{' "$tmp" | tail -n 1 || true)"
    rm -f "$tmp"
    [[ -n "$line" ]] || die "no JSON line printed by: $*"
    echo "$line" >&2
    echo "$line" >> "$results"
}

# mode height width reps
specs=(
    "infer 368 496 $REPS_INFER"
    "infer 480 1440 $REPS_INFER"
    "train 128 128 $REPS_TRAIN"
)
for spec in "${specs[@]}"; do
    read -r mode h w reps <<< "$spec"
    for m in raft_small raft_large; do
        measure env OMP_NUM_THREADS=2 MKL_NUM_THREADS=2 "$PYTHON" scripts/bench_raft.py \
            --model "$m" --mode "$mode" --height "$h" --width "$w" --reps "$reps" --threads 2
    done
    for m in mms-small mms; do
        measure env RAYON_NUM_THREADS=2 "$PINS" bench-flow \
            --model "$m" --mode "$mode" --height "$h" --width "$w" --reps "$reps"
    done
done

"$PYTHON" - "$results" "$out/summary.md" <<'PY'
import json, sys

rows = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]

def key(r):
    return r["tool"].replace("_", "-")

s = "| tool | mode | size | ms | peak RSS MB | params |\n|---|---|---|---|---|---|\n"
for r in rows:
    s += (f"| {r['tool']} | {r['mode']} | {r['height']}x{r['width']} | {r['ms']:.1f} | "
          f"{r['peak_rss_mb']:.0f} | {r['params'] / 1e6:.2f} M |\n")
s += "\nratios (RAFT / pins: >1 means pins is faster or uses less memory)\n\n"
s += "| pins | RAFT | mode | size | time ratio | memory ratio |\n|---|---|---|---|---|---|\n"
missing = []
for pins, raft in (("pins mms", "torchvision raft-large"), ("pins mms-small", "torchvision raft-small")):
    for r in rows:
        if key(r) != raft:
            continue
        q = [p for p in rows if key(p) == pins and (p["mode"], p["height"], p["width"]) == (r["mode"], r["height"], r["width"])]
        if not q:
            missing.append(f"{pins} {r['mode']} {r['height']}x{r['width']}")
            continue
        p = q[0]
        s += (f"| {p['tool']} | {r['tool']} | {r['mode']} | {r['height']}x{r['width']} | "
              f"{r['ms'] / p['ms']:.2f}x | {r['peak_rss_mb'] / p['peak_rss_mb']:.2f}x |\n")
print("\n" + s, end="")
open(sys.argv[2], "w").write(s)
if missing:
    sys.exit("bench_flow_compare: error: no pins result matching " + ", ".join(missing))
PY
echo "results: $results, table: $out/summary.md" >&2
