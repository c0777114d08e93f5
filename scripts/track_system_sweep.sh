#!/usr/bin/env bash
# The whole system (camera frames → MMS → tracks, tests/track_system.rs's pipeline and clips)
# on many seeds at once: for each SEED, the four clips SEED…SEED+3 (a sinusoid, a spiral and a
# random path of one disc, and five discs), rendered through the default camera, tracked at the
# shipped defaults and scored against their truth. Clips are rendered 6 at a time and tracked
# JOBS (4) at a time; each clip's frames are deleted once scored.
#
#   scripts/track_system_sweep.sh PINS OUT SEED...
#
# PINS: a pins binary (built with `--features wgpu` for DEVICE=wgpu); DEVICE: cpu (default) or
# a GPU backend of that build; WEIGHTS: the tracker's MMS weights (default: its own, mms-small);
# CONFIG: a tracking config file (`pins track --config`, e.g. a profile and the tracker keys it
# changes; default: none, the shipped defaults);
# KINDS: the clip kinds to run (default: "sinusoid spiral random five"; each keeps its seed
# offset, so `KINDS=sinusoid` runs the sinusoids of the full sweep); OUT: a folder for
# summary.txt (`pins track eval`'s table per clip) and evals.jsonl (one line per clip:
# {"name", "eval": the eval JSON}), which scripts/track_system_summary.py reads. WORK (default: a
# temporary folder) holds the clips.
set -uo pipefail
B=$(realpath "${1:?usage: track_system_sweep.sh PINS OUT SEED...}")
O=$(realpath -m "${2:?usage: track_system_sweep.sh PINS OUT SEED...}")
shift 2
[ $# -gt 0 ] || { echo "give at least one seed" >&2; exit 2; }
for s in "$@"; do
    [[ $s =~ ^[0-9]+$ ]] || { echo "seed must be a non-negative integer, got '$s'" >&2; exit 2; }
done
DEVICE=${DEVICE:-cpu}
WEIGHTS=${WEIGHTS:-}
CONFIG=${CONFIG:+$(realpath "$CONFIG")}
if [ -n "$CONFIG" ] && [ ! -f "$CONFIG" ]; then
    echo "CONFIG: no such file: $CONFIG" >&2
    exit 2
fi
KINDS=${KINDS:-sinusoid spiral random five}
for kind in $KINDS; do
    case $kind in
        sinusoid | spiral | random | five) ;;
        *) echo "KINDS: unknown clip kind '$kind' (sinusoid, spiral, random, five)" >&2; exit 2 ;;
    esac
done
JOBS=${JOBS:-4}
FRAMES=${FRAMES:-150}
W=${WORK:-$(mktemp -d)}
mkdir -p "$O" "$W" || exit 1
cd "$W" || exit 1
t0=$(date +%s)

# The scene of tests/track_system.rs for a clip kind and seed.
scene() {
    local o
    case $1 in
        sinusoid) o='[{"path":"sinusoid","radius":16}]' ;;
        spiral) o='[{"path":"spiral","radius":16}]' ;;
        random) o='[{"path":"random","radius":18}]' ;;
        five) o='[{"path":"sinusoid","radius":15},{"path":"line","radius":14,"from":[1.1,0.35],"to":[-0.1,0.7]},{"path":"spiral","radius":16,"start":0.4},{"path":"random","radius":16},{"path":"line","radius":15,"from":[0.3,1.1],"to":[0.8,-0.1],"start":0.8}]' ;;
    esac
    echo "{\"scene\":{\"width\":640,\"height\":480,\"fps\":30,\"frames\":$FRAMES,\"seed\":$2,\"objects\":$o}}"
}

: > list.txt
for s in "$@"; do
    k=0
    for kind in sinusoid spiral random five; do
        n=${kind}_$((s + k))
        if [[ " $KINDS " == *" $kind "* ]]; then
            scene $kind $((s + k)) > "$n.json"
            echo "$n" >> list.txt
        fi
        k=$((k + 1))
    done
done

# Render in the background; each clip marks itself rendered (or failed).
(xargs -P 6 -I{} sh -c "'$B' track render --config {}.json --out {} > {}.render.log 2>&1 && touch {}.rendered || touch {}.failed" < list.txt) &

track() {
    local n=$1
    while [ ! -e "$n.rendered" ] && [ ! -e "$n.failed" ]; do sleep 1; done
    if [ -e "$n.failed" ] ||
        ! "$B" track --frames "$n/frames" --out "${n}_t" --iters 4 --no-plots --device "$DEVICE" ${WEIGHTS:+--weights "$WEIGHTS"} ${CONFIG:+--config "$CONFIG"} > "$n.track.log" 2>&1 ||
        ! "$B" track eval --tracks "${n}_t/tracks.json" --truth "$n/truth.json" --out "$n.eval.json" > "$n.eval.txt" 2>&1; then
        (flock 9; echo "## $n FAILED: $(tail -n 2 "$n".*.log | tr '\n' ' ')" >> "$O/summary.txt") 9> lock
        rm -rf "$n"
        return
    fi
    (
        flock 9
        echo "## $n [$(($(date +%s) - t0)) s]" >> "$O/summary.txt"
        cat "$n.eval.txt" >> "$O/summary.txt"
        echo "{\"name\":\"$n\",\"eval\":$(tr -d '\n' < "$n.eval.json")}" >> "$O/evals.jsonl"
    ) 9> lock
    rm -rf "$n"
}
export -f track
export B O t0 DEVICE WEIGHTS CONFIG
xargs -P "$JOBS" -I{} bash -c 'track {}' < list.txt
wait
echo "# done [$(($(date +%s) - t0)) s]" >> "$O/summary.txt"
