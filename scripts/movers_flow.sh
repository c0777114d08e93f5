#!/usr/bin/env bash
# How much of a camouflaged mover's motion a flow method reports: the pairs of
# experiments/movers_eval.json (40 pairs of the tracking clips' scenes, a seed no training
# config uses), each method's flow, and scripts/flow_response.py over the moving pixels (every
# still background pixel has zero true flow and is left out of its bands).
#
#   scripts/movers_flow.sh OUT [WEIGHTS[@ITERS[@START[@SCALE]]] ...] [dis]
#
# WEIGHTS is what `pins infer --weights` takes (mms-small, mms-small-real, a file); ITERS
# defaults to 4, START to zero and SCALE (`pins infer --scale`: the network at this multiple of
# the frames' size) to 1; no refinement. The tracker's flow is mms-small-real@4@zero@2. `dis` is OpenCV's DIS
# medium (scripts/dis_flows.py; needs opencv-python-headless). PINS names the binary (default:
# pins on the PATH), PYTHON the interpreter (default python3), EVAL the pairs' generator config
# (default experiments/movers_eval.json; experiments/movers_eval_320.json: a 320x240 camera's,
# whose tracker runs MMS at @4@zero@4).
set -euo pipefail
cd "$(dirname "$0")/.."
die() { echo "movers_flow: $*" >&2; exit 1; }
[ $# -ge 2 ] || die "usage: scripts/movers_flow.sh OUT METHOD [METHOD ...] (METHOD: WEIGHTS[@ITERS[@START[@SCALE]]] or dis)"
PINS=${PINS:-pins}
PYTHON=${PYTHON:-python3}
EVAL=${EVAL:-experiments/movers_eval.json}
out=$1; shift
data=$out/pairs
"$PINS" generate --config "$EVAL" --out "$data" --quiet >/dev/null
n=$(ls "$data"/*_flow.flo | wc -l)
[ "$n" -gt 0 ] || die "no pairs in $data"
for method in "$@"; do
    if [ "$method" = dis ]; then
        name=dis_medium
    else
        IFS=@ read -r weights iters start scale <<<"$method"
        iters=${iters:-4}; start=${start:-zero}; scale=${scale:-1}
        name="$(basename "$weights" .safetensors)_${iters}it_$start"
        [ "$scale" = 1 ] || name="${name}_x$scale"
    fi
    dir=$out/$name
    mkdir -p "$dir"
    pairs=()
    for truth in "$data"/*_flow.flo; do
        i=$(basename "$truth" _flow.flo)
        est=$dir/$i.flo
        if [ ! -s "$est" ]; then
            if [ "$method" = dis ]; then
                tmp=$(mktemp -d)
                cp "$data/${i}_img1.png" "$tmp/0.png"
                cp "$data/${i}_img2.png" "$tmp/1.png"
                "$PYTHON" scripts/dis_flows.py --frames "$tmp" --out "$tmp/flow" >/dev/null
                mv "$tmp/flow/00000.flo" "$est.part" && mv "$est.part" "$est"
                rm -r "$tmp"
            else
                "$PINS" infer --img1 "$data/${i}_img1.png" --img2 "$data/${i}_img2.png" \
                    --weights "$weights" --iters "$iters" --start "$start" --refine none --scale "$scale" \
                    --out "$est" >/dev/null
            fi
        fi
        pairs+=("$est:$truth")
    done
    echo "== $name"
    "$PYTHON" scripts/flow_response.py "${pairs[@]}"
done
