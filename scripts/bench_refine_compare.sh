#!/usr/bin/env bash
# One run, one machine: the variational refinement of pins (`pins bench-flow --mode refine`,
# scales 4, 2, 1) against OpenCV's cv2.VariationalRefinement (full resolution only, the same
# α, δ, γ, iterations and ω) on the same pair — a procedural texture and a smoothly warped copy,
# 8-bit, with a start flow as rough as a 1/8-resolution estimate, written by pins --pair-out and
# read by scripts/bench_refine_opencv.py — at 384x512 and 480x640, on 1 and 2 threads.
# Prints the JSON lines (ms = median of REPS after a warm-up; epe_start / epe_refined against
# the true flow) and collects them in out/bench_refine/results.jsonl.
#
# Usage: bash scripts/bench_refine_compare.sh   (from anywhere; runs from the repo root)
# Environment: REPS (5); PINS, the binary (default: built with cargo build --release);
#              PINS_BEFORE, a second binary to time beside it (e.g. one built before a change);
#              PYTHON (python3) with cv2 and numpy.
set -euo pipefail
cd "$(dirname "$0")/.."

export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/pins-target}"
REPS="${REPS:-5}"
PYTHON="${PYTHON:-python3}"
out="out/bench_refine"
die() { echo "bench_refine_compare: error: $*" >&2; exit 1; }

[[ "$REPS" =~ ^[1-9][0-9]*$ ]] || die "REPS must be a positive integer, got '$REPS'"
"$PYTHON" -c "import cv2, numpy" 2>/dev/null || die "$PYTHON cannot import cv2 and numpy"
if [[ -z "${PINS:-}" ]]; then
    PINS="$CARGO_TARGET_DIR/release/pins"
    cargo build --release --quiet || die "cargo build --release failed"
fi
[[ -x "$PINS" ]] || die "pins binary not found or not executable: $PINS"

mkdir -p "$out"
: > "$out/results.jsonl"
echo "$(uname -srm), $(nproc) cores, commit $(git rev-parse --short HEAD 2>/dev/null || echo unknown)" >&2
for threads in 1 2; do
    for size in "384 512" "480 640"; do
        read -r h w <<< "$size"
        pair="$out/pair_${h}x${w}"
        {
            RAYON_NUM_THREADS=$threads "$PINS" bench-flow --mode refine --height "$h" --width "$w" \
                --reps "$REPS" --pair-out "$pair"
            if [[ -n "${PINS_BEFORE:-}" ]]; then
                RAYON_NUM_THREADS=$threads "$PINS_BEFORE" bench-flow --mode refine --height "$h" \
                    --width "$w" --reps "$REPS" | sed 's/"pins refine"/"pins refine (before)"/'
            fi
            "$PYTHON" scripts/bench_refine_opencv.py --pair "$pair" --reps "$REPS" --threads "$threads"
        } | tee -a "$out/results.jsonl"
    done
done
