#!/usr/bin/env bash
# One run, one machine: the pins camera model against the same chain in numpy/scipy.
# Prints both tables and the throughput ratios (one core each) that docs/performance.md quotes.
# Needs: python3 with numpy and scipy (pip install numpy scipy).
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/pins-target}"
out="${1:-out/bench}"
mkdir -p "$out"
cargo build --release --quiet
"$CARGO_TARGET_DIR/release/pins" bench --json "$out/pins.json"
OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 python3 scripts/bench_pipeline.py --json "$out/numpy.json"
python3 - "$out/pins.json" "$out/numpy.json" <<'PY'
import json, sys
p, n = (json.load(open(f)) for f in sys.argv[1:3])
print(f"\npins against {n['tool']} (one core each; >1 means pins is faster)")
for r in n["pipeline"]:
    for q in p["pipeline"]:
        if (q["height"], q["width"]) == (r["height"], r["width"]):
            print(f"  pipeline {r['height']}x{r['width']}, pins {q['threads']} thread(s): "
                  f"{q['ms_per_frame']:.1f} ms vs {r['ms_per_frame']:.1f} ms -> {r['ms_per_frame'] / q['ms_per_frame']:.2f}x")
for r in n["convolution"]:
    for q in p["convolution"]:
        if q["psf_size"] == r["psf_size"]:
            best = min(v for v in (q["direct_ms"], q["fft_ms"]) if v is not None)
            best_ratio = r["fft_ms"] / best
            print(f"  convolution {r['psf_size']}x{r['psf_size']}: pins {best:.1f} ms vs scipy {r['fft_ms']:.1f} ms -> {best_ratio:.2f}x")
PY
