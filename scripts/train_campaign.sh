#!/usr/bin/env bash
# The training campaign of the MMS network: one long run (experiments/campaign/train.json) on
# the campaign's stream (experiments/campaign/stream.json: the generator configs of data/*.json
# with their weights, each pair made in memory when a step needs it and never seen twice),
# continued a session at a time, on the CPU in the background or on a GPU machine.
#
#   scripts/train_campaign.sh [run] [BUDGET]       continue on this machine's CPU, niced (BUDGET
#                                                  as pins train --time-budget; default 2h).
#                                                  With COOLDOWN_MINUTES=M, the last M minutes
#                                                  of BUDGET cool a branch of the run down (as
#                                                  `cooldown`, its length from the session's
#                                                  mean step), so that a session ends with
#                                                  weights worth scoring; not when the run was
#                                                  stopped before its budget (SIGTERM)
#   scripts/train_campaign.sh gpu MINUTES OUTDIR   continue on a GPU (--device wgpu) until MINUTES
#                                                  (at most 9) after the script started, and
#                                                  copy the checkpoint,
#                                                  weights, the mean of the session's snapshots,
#                                                  log and pairs/s to OUTDIR (each file under
#                                                  16 MiB). With COOLDOWN_MINUTES=M (less than
#                                                  MINUTES), the last M minutes cool a branch of
#                                                  the run down instead (as `cooldown`, its
#                                                  length from the session's mean step:
#                                                  OUTDIR/cooldown.safetensors and
#                                                  cooldown_log.csv)
#   scripts/train_campaign.sh cooldown STEPS [BUDGET]
#                                                  cool a branch of the run down (pins train
#                                                  --branch-from --cooldown): the learning rate
#                                                  taken to zero over STEPS from where the run
#                                                  stands, into $WORK/cooldown-STEP (STEP: the
#                                                  run's step; a rerun resumes it), on the
#                                                  campaign's cooldown.json where it has one
#                                                  (else its stream.json); the run itself goes
#                                                  on later from its own checkpoint
#   scripts/train_campaign.sh status               where the campaign stands
#   scripts/train_campaign.sh average [N]          the mean of the campaign's last N snapshots
#                                                  (default 5; stochastic weight averaging): the
#                                                  snapshots of every checkpoint on this machine
#                                                  ($WORK/snapshots), the run's last.safetensors
#                                                  and the committed versions of the campaign's
#                                                  weights in git history, newest first,
#                                                  duplicates once, only those of the newest
#                                                  one's run (config and data in the training
#                                                  stamp; no cool-downs), by `pins average` into
#                                                  $WORK/average.safetensors
#
# Where a session starts, in order: the run folder's checkpoint ($WORK/run, --resume: exactly
# where it stopped); else a checkpoint folder brought from elsewhere (CHECKPOINT=DIR holding
# state.json, model-*.bpk, optim-*.bin, log.csv); else the campaign's last committed weights
# (experiments/campaign/weights.safetensors, --continue-from: the step its training stamp
# records, with a learning-rate warm-up); else the shipped mms-small-real weights at step 0 (--init).
# A session ends at its budget, on SIGTERM or Ctrl-C with a checkpoint; a kill loses at most
# ten minutes. After a session, `status` prints the step, the pairs seen and the hours.
#
# Environment: PINS (a pins binary; default: built here with cargo), WORK (default
# out/campaign: run, snapshots, cool-downs), CAMPAIGN (default experiments/campaign), DEVICE (gpu mode,
# default wgpu), NEW_SCHEDULE=1 (start a new schedule from the campaign's weights with --init
# after its config changed).
set -euo pipefail
cd "$(dirname "$0")/.."
t_script=$(date +%s)
CAMPAIGN=${CAMPAIGN:-experiments/campaign}
WORK=${WORK:-out/campaign}
RUN=$WORK/run
CONFIG=$CAMPAIGN/train.json
STREAM=$CAMPAIGN/stream.json
# The mix a cool-down anneals on (warmup–stable–decay's decay phase on data of its own), where
# the campaign has one; else the run's stream.
COOL_STREAM=$CAMPAIGN/cooldown.json
[ -f "$COOL_STREAM" ] || COOL_STREAM=$STREAM
WEIGHTS=$CAMPAIGN/weights.safetensors
START=datasets/weights/mms-small-real.safetensors

die() { echo "train_campaign: $*" >&2; exit 1; }
mode=${1:-run}
case "$mode" in
    run | gpu | status | average | cooldown) shift || true ;;
    *) mode=run ;;
esac

[ -d "$CAMPAIGN" ] || die "no campaign folder $CAMPAIGN"
[ -f "$CONFIG" ] || die "the campaign folder $CAMPAIGN has no train.json"
[ -f "$STREAM" ] || die "the campaign folder $CAMPAIGN has no stream.json"
shopt -s nullglob

if [ -z "${PINS:-}" ]; then
    cargo build --release --locked --quiet
    PINS="$(cargo metadata --format-version 1 --no-deps |
        python3 -c 'import json,sys; print(json.load(sys.stdin)["target_directory"])')/release/pins"
fi
[ -x "$PINS" ] || die "no pins binary at $PINS"

# Where the campaign stands: the checkpoint's step, pairs seen and hours, the last validation.
status() {
    python3 - "$RUN" "$WEIGHTS" "$CONFIG" <<'PY'
import csv, json, os, struct, sys
run, weights, config = sys.argv[1:4]
batch = json.load(open(config))["batch_size"]
state = os.path.join(run, "checkpoint", "state.json")
if os.path.isfile(state):
    s = json.load(open(state))
    print(f"checkpoint {state}: step {s['step']} of {s['config']['steps']}, "
          f"{s['step'] * s['config']['batch_size']} pairs seen, {s['train_seconds'] / 3600:.2f} h of training, "
          f"best validation EPE {s.get('best_val_epe')}")
else:
    print(f"no checkpoint in {run}")
if os.path.isfile(weights):
    b = open(weights, "rb").read()
    n = struct.unpack("<Q", b[:8])[0]
    meta = json.loads(b[8:8 + n]).get("__metadata__", {})
    st = json.loads(meta.get("pins.training", "null") or "null")
    if st:
        print(f"committed weights {weights}: step {st['step']} of {st['steps']}, "
              f"{st['pairs_seen']} pairs seen")
log = os.path.join(run, "log.csv")
if os.path.isfile(log):
    rows = list(csv.DictReader(open(log)))
    val = [r for r in rows if r.get("val_epe")]
    if rows:
        last = rows[-1]
        recent = sorted(float(r["ms_per_step"]) for r in rows[-50:])
        ms = recent[len(recent) // 2]
        print(f"last step {last['step']}: loss {float(last['loss']):.3f}; median of the last "
              f"{len(recent)} steps {ms:.0f} ms per step ({batch / ms * 1e3:.2f} pairs/s)")
    if val:
        print(f"last validation (step {val[-1]['step']}): EPE {float(val[-1]['val_epe']):.3f}, "
              f"1 px {float(val[-1]['val_px1']):.3f}")
PY
}
# The run's checkpointed step (0 without one).
checkpoint_step() {
    if [ -f "$RUN/checkpoint/state.json" ]; then
        python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["step"])' "$RUN/checkpoint/state.json"
    else
        echo 0
    fi
}

# Seconds in a duration written as pins train --time-budget takes it (2h30m, 90m, 45s).
seconds_of() {
    python3 - "$1" <<'PY'
import re, sys
m = re.fullmatch(r"(?:(\d+)h)?(?:(\d+)m)?(?:(\d+)s)?", sys.argv[1].strip())
if not m or not any(m.groups()):
    sys.exit(1)
print(sum(int(g or 0) * k for g, k in zip(m.groups(), (3600, 60, 1))))
PY
}

# COOLDOWN_MINUTES as a whole number (0 when unset).
cool_minutes() {
    local c=${COOLDOWN_MINUTES:-0}
    [[ "$c" =~ ^[0-9]+$ ]] || die "COOLDOWN_MINUTES must be a whole number of minutes, got '$c'"
    echo $((10#$c))
}

# cool_down_tail MINUTES SINCE SECONDS [ARGS...]: cools a branch of the run down from where it
# stands, over as many steps as 80 % of MINUTES hold at the mean of this session's last 100
# steps (those after step SINCE; the rest is for its validations and last step; the mean, not
# the median, since a stream of two crop sizes makes steps of two lengths), at most the steps
# the run has left, within SECONDS; ARGS go to pins train (a device), NICE prefixes it. Sets
# `cooled` to the branch's folder when it ran.
cool_down_tail() {
    local cool=$1 since=$2 left=$3 plan at steps branch done_at
    shift 3
    cooled=""
    local state="$RUN/checkpoint/state.json"
    [ -f "$state" ] || die "the run wrote no checkpoint to cool down from"
    plan=$(python3 - "$state" "$RUN/log.csv" "$cool" "$since" <<'PY'
import json, statistics, sys
state, log, cool, since = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
s = json.load(open(state))
rows = [l.split(",") for l in open(log).read().splitlines()[1:]]
# This session's steps only (a carried log holds other machines' rows before them).
ms = [float(r[5]) for r in rows if len(r) > 5 and r[5] and int(r[0]) > since][-100:]
n = int(0.8 * cool * 60e3 / statistics.mean(ms)) if ms else 0
print(s["step"], max(0, min(n, s["config"]["steps"] - s["step"])))
PY
    ) || die "cannot plan the cool-down from $state and $RUN/log.csv"
    read -r at steps <<<"$plan"
    if [ "$left" -lt 30 ]; then
        echo "no cool-down: only ${left} s are left"
    elif [ "$steps" -ge 1 ]; then
        branch="$WORK/cooldown-$at"
        echo "cooling down: --branch-from $RUN → $branch over $steps steps ${*}"
        ${NICE:-} "$PINS" train --quiet --config "$CONFIG" --data "$COOL_STREAM" --out "$branch" \
            --branch-from "$RUN" --cooldown "$steps" "$@" --time-budget "${left}s"
        cooled=$branch
        done_at=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["step"])' "$branch/checkpoint/state.json")
        if [ "$done_at" -eq $((at + steps)) ]; then
            echo "cool-down complete: steps $at to $done_at, weights $branch/last.safetensors"
        else
            echo "cool-down stopped at step $done_at of $at to $((at + steps)): its weights are not cooled"
        fi
    else
        echo "no cool-down: the run has no steps left, or the session measured none"
    fi
}

if [ "$mode" = status ]; then
    status
    exit 0
fi

if [ "$mode" = average ]; then
    n=${1:-5}
    [[ "$n" =~ ^[0-9]+$ ]] && [ "$n" -ge 2 ] || die "average: N must be an integer of at least 2, got $n"
    mkdir -p "$WORK/snapshots"
    mkdir -p "$WORK/history"
    candidates=()
    # This machine's snapshots, newest first; then the run's weights; then git history.
    while IFS= read -r f; do candidates+=("$f"); done < <(ls -r "$WORK"/snapshots/step-*.safetensors 2>/dev/null)
    if [ -f "$RUN/last.safetensors" ]; then candidates+=("$RUN/last.safetensors"); fi
    for c in $(git log --format=%h -- "$WEIGHTS" 2>/dev/null || true); do
        git show "$c:$WEIGHTS" > "$WORK/history/$c.safetensors" 2>/dev/null || continue
        candidates+=("$WORK/history/$c.safetensors")
    done
    # Only weights of the newest file's run: the same config and data in their training stamp,
    # and none of a cool-down (an earlier campaign, or a branch, is another run).
    run_of() {
        python3 - "$1" <<'PY'
import json, struct, sys
try:
    b = open(sys.argv[1], "rb").read()
    n = struct.unpack("<Q", b[:8])[0]
    st = json.loads(json.loads(b[8:8 + n]).get("__metadata__", {}).get("pins.training") or "null")
except Exception:
    st = None
if st and not st.get("cooldown"):
    print(json.dumps([st["config"], st["data"]], sort_keys=True))
PY
    }
    files=()
    seen=" "
    run=""
    for f in "${candidates[@]}"; do
        sum=$(sha256sum "$f" | cut -d' ' -f1)
        case "$seen" in *" $sum "*) continue ;; esac
        seen+="$sum "
        this=$(run_of "$f")
        [ -n "$this" ] || continue
        [ -n "$run" ] || run=$this
        [ "$this" = "$run" ] || continue
        files+=("$f")
        [ "${#files[@]}" -lt "$n" ] || break
    done
    [ "${#files[@]}" -ge 2 ] ||
        die "average: fewer than 2 snapshots in $WORK/snapshots, $RUN and git history (a shallow clone has none)"
    "$PINS" average "${files[@]}" --out "$WORK/average.safetensors"
    exit 0
fi

echo "data: pairs made on the fly from $STREAM"

# A cool-down branches off the run where it stands (warmup–stable–decay: the run stays at its
# schedule's rate, each branch ends at zero and is what gets scored and shipped).
if [ "$mode" = cooldown ]; then
    steps=${1:-}
    [[ "$steps" =~ ^[0-9]+$ ]] && [ "$steps" -ge 1 ] ||
        die "cooldown: STEPS must be a positive integer, got '${steps}'"
    [ -f "$RUN/checkpoint/state.json" ] || die "cooldown: $RUN has no checkpoint to branch from"
    at=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["step"])' "$RUN/checkpoint/state.json")
    branch="$WORK/cooldown-$at"
    if [ -f "$branch/checkpoint/state.json" ]; then
        from=(--resume)
    else
        from=(--branch-from "$RUN")
    fi
    echo "cooling down: ${from[*]} → $branch over $steps steps"
    nice -n 19 "$PINS" train --quiet --config "$CONFIG" --data "$COOL_STREAM" --out "$branch" \
        "${from[@]}" --cooldown "$steps" --time-budget "${2:-2h}"
    echo "cool-down weights: $branch/last.safetensors"
    exit 0
fi

# Where this session starts.
start=()
if [ -f "$RUN/checkpoint/state.json" ]; then
    start=(--resume)
elif [ -n "${CHECKPOINT:-}" ]; then
    [ -f "$CHECKPOINT/state.json" ] || die "CHECKPOINT=$CHECKPOINT holds no state.json"
    mkdir -p "$RUN/checkpoint.tmp"
    cp "$CHECKPOINT"/state.json "$CHECKPOINT"/model-*.bpk "$CHECKPOINT"/optim-*.bin "$RUN/checkpoint.tmp/" ||
        die "CHECKPOINT=$CHECKPOINT lacks its model-*.bpk or optim-*.bin"
    for f in log.csv last.safetensors best.safetensors; do
        if [ -f "$CHECKPOINT/$f" ]; then cp "$CHECKPOINT/$f" "$RUN/$f"; fi
    done
    mv "$RUN/checkpoint.tmp" "$RUN/checkpoint"
    start=(--resume)
elif [ -f "$WEIGHTS" ] && [ -z "${NEW_SCHEDULE:-}" ]; then
    start=(--continue-from "$WEIGHTS")
elif [ -f "$WEIGHTS" ]; then
    start=(--init "$WEIGHTS")
else
    start=(--init "$START")
fi
echo "starting: ${start[*]}"

# Every checkpoint's weights are also kept as a snapshot ($WORK/snapshots/step-N.safetensors,
# every 100 steps and every ten minutes) for `average`.
if [ "$mode" = run ]; then
    budget=${1:-2h}
    cool=$(cool_minutes)
    run_budget=$budget
    if [ "$cool" -gt 0 ]; then
        total=$(seconds_of "$budget") || die "BUDGET must be hours, minutes and seconds such as 2h30m, 90m or 45s, got '$budget'"
        [ "$total" -gt $((cool * 60 + 60)) ] ||
            die "COOLDOWN_MINUTES ($cool) leaves no time of the budget $budget for the run"
        # Less the cool-down's minutes and 30 s for the run's last step and the status.
        run_budget="$((total - cool * 60 - 30 - ($(date +%s) - t_script)))s"
    fi
    from_step=$(checkpoint_step)
    log_file=$(mktemp)
    nice -n 19 "$PINS" train --quiet --config "$CONFIG" --data "$STREAM" --out "$RUN" \
        "${start[@]}" --time-budget "$run_budget" --snapshots "$WORK/snapshots" | tee "$log_file"
    status
    if [ "$cool" -gt 0 ]; then
        if grep -q "stopped by its time budget" "$log_file"; then
            left=$(($(seconds_of "$budget") - ($(date +%s) - t_script) - 20))
            NICE="nice -n 19" cool_down_tail "$cool" "$from_step" "$left"
        else
            echo "no cool-down: the run did not end at its time budget"
        fi
    fi
    rm -f "$log_file"
    exit 0
fi

# gpu MINUTES OUTDIR
minutes=${1:?usage: train_campaign.sh gpu MINUTES OUTDIR}
outdir=${2:?usage: train_campaign.sh gpu MINUTES OUTDIR}
[ "$minutes" -ge 1 ] && [ "$minutes" -le 9 ] || die "MINUTES must be in 1..9, got $minutes"
mkdir -p "$outdir"
t0=$(date +%s)
cool=${COOLDOWN_MINUTES:-0}
[[ "$cool" =~ ^[0-9]+$ ]] && [ "$((10#$cool))" -lt "$minutes" ] ||
    die "COOLDOWN_MINUTES must be a whole number of minutes below MINUTES ($minutes), got '$cool'"
cool=$((10#$cool))
# What is left of the minutes once started, less 30 s for the last step and the copy, less the
# cool-down's minutes.
left=$((minutes * 60 - (t0 - t_script) - 30 - cool * 60))
[ "$left" -ge 10 ] || die "only ${left} s are left of ${minutes} min for the run"
echo "training for at most ${left} s on ${DEVICE:-wgpu}"
mkdir -p "$WORK/snapshots"
before=" $(cd "$WORK/snapshots" && echo *.safetensors) "
# The step this session starts at (its own rows of the log come after it).
from_step=$(checkpoint_step)
"$PINS" train --quiet --config "$CONFIG" --data "$STREAM" --out "$RUN" --device "${DEVICE:-wgpu}" \
    "${start[@]}" --time-budget "${left}s" --snapshots "$WORK/snapshots"
echo "trained for $(($(date +%s) - t0)) s on ${DEVICE:-wgpu}"
status | tee "$outdir/status.txt"
state="$RUN/checkpoint/state.json"
[ -f "$state" ] || die "the run wrote no checkpoint"
model=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["model_file"])' "$state")
optim=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["optimizer_file"])' "$state")
cp "$state" "$RUN/checkpoint/$model" "$RUN/checkpoint/$optim" "$RUN/log.csv" "$RUN/last.safetensors" "$outdir/"
if [ -f "$RUN/best.safetensors" ]; then cp "$RUN/best.safetensors" "$outdir/"; fi
# The mean of this session's snapshots (stochastic weight averaging), where it kept two or more.
session=()
for f in "$WORK"/snapshots/step-*.safetensors; do
    case "$before" in *" $(basename "$f") "*) continue ;; esac
    [ -f "$f" ] && session+=("$f")
done
if [ "${#session[@]}" -ge 2 ]; then
    "$PINS" average "${session[@]}" --out "$outdir/average.safetensors"
fi
if [ "$cool" -gt 0 ]; then
    cool_down_tail "$cool" "$from_step" $((minutes * 60 - ($(date +%s) - t_script) - 20)) \
        --device "${DEVICE:-wgpu}"
    if [ -n "${cooled:-}" ]; then
        cp "$cooled/last.safetensors" "$outdir/cooldown.safetensors"
        cp "$cooled/log.csv" "$outdir/cooldown_log.csv"
    fi
fi
ls -l "$outdir"
