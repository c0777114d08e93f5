#!/usr/bin/env python3
"""The shipping rule of the training ledger, applied to reports the commands wrote.

Candidate weights replace the shipped `mms-small-real` only when, on `pins bench-real --config
experiments/bench_real.json` at 12 iterations with the flow commands' defaults (the refined rows,
"mms-small + variational", where the reports have them):

  1. through the camera, the EPE over all known pixels is lower than the shipped weights';
  2. no real set, through the camera or clean, has an EPE more than 2 % above the shipped
     weights' (`--tolerance`);

and every Note S12 report given (`pins detect-limits ... --out DIR`, DIR/report.json; the
defaults and `--start zero`) detects every case at every iteration count.

    scripts/shipping_rule.py CANDIDATE/report.json SHIPPED/report.json [--s12 DIR/report.json ...]

Both bench-real reports must come from the same build and config (a comparison is always
between weights scored with the same refinement). Prints one row per set and camera and the
verdict, then for each set outside the tolerance its pairs (the set's EPE is over all its pixels,
so one pair can decide it), each with its EPE over pixels moving 40 px or more where the reports
have it; exits 0 when the candidate ships, 1 when it does not, 2 on unusable input.
"""
import argparse
import json
import sys

ITERS = 12
# MPI-Sintel's speed classes of `by_speed` (src/flow/metrics.rs): below 10 px, 10-40, 40 or more.
SPEED_CLASSES = ("s0-10", "s10-40", "s40+")


def fail(msg):
    print(f"shipping_rule: {msg}", file=sys.stderr)
    sys.exit(2)


def load(path):
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, json.JSONDecodeError) as e:
        fail(f"{path}: {e}")


def method_of(methods):
    """The refined row when the report has one (the defaults), else the network alone."""
    names = {m["method"] for m in methods if m.get("iters") == ITERS}
    for name in ("mms-small + variational", "mms-small", "mms + variational", "mms"):
        if name in names:
            return name
    refined = sorted(n for n in names if n.endswith("+ variational"))
    if refined:
        return refined[0]
    if names:
        return sorted(names)[0]
    return None


def row_of(methods, method):
    return next((x for x in methods if x["method"] == method and x.get("iters") == ITERS), None)


def pairs(report, method):
    """{(set, camera): [(name, source, mean |flow|, epe, s40+ epe or None)]} of the report's
    12-iteration rows of `method` (empty for reports without `per_pair`)."""
    out = {}
    for run in report.get("runs", []):
        rows = []
        for p in run.get("per_pair", []):
            m = row_of(p.get("methods", []), method)
            if m is None:
                continue
            speed = m.get("by_speed") or {}
            fast = None
            if len(speed.get("pixels", [])) == 3 and speed["pixels"][2]:
                fast = speed["epe"][2]
            rows.append((p.get("name", "?"), p.get("source", "?"), p.get("mean_gt", 0.0),
                         m["epe"], fast))
        out[(run["set"], run["camera"])] = rows
    return out


def scores(report, path):
    """{(set, camera): epe}, {camera: pooled epe} and {camera: pooled by_speed} of the report's
    12-iteration MMS rows (by_speed where the report has it)."""
    runs = report.get("runs")
    if not isinstance(runs, list) or not runs:
        fail(f"{path}: no runs (is it a `pins bench-real` report.json?)")
    per_set, method = {}, None
    for run in runs:
        m = method_of(run.get("methods", []))
        if m is None:
            fail(f"{path}: set {run.get('set')} has no MMS row at {ITERS} iterations")
        method = method or m
        if m != method:
            fail(f"{path}: sets scored by different methods ({method}, {m})")
        row = row_of(run["methods"], m)
        per_set[(run["set"], run["camera"])] = row["epe"]
    pooled, speeds = {}, {}
    for s in report.get("summary", []):
        if s["pooled"]["method"] == method and s["pooled"].get("iters") == ITERS:
            pooled[s["camera"]] = s["pooled"]["epe"]
            if "by_speed" in s["pooled"]:
                speeds[s["camera"]] = s["pooled"]["by_speed"]
    if "camera" not in pooled:
        fail(f"{path}: no pooled score through the camera for {method}")
    return method, per_set, pooled, speeds


def s12_misses(report, path):
    cases = report.get("scores")
    if not isinstance(cases, list) or not cases:
        fail(f"{path}: no scores (is it a `pins detect-limits` report.json?)")
    start = report.get("start", "?")
    return [
        f"{c['case']} @{c['iters']} ({start} start)" for c in cases if not c.get("detected")
    ]


def print_pairs(keys, cand, ship):
    """Per pair of each set outside the tolerance: which pairs moved the set's EPE."""
    keys = [k for k in keys if cand.get(k) and ship.get(k)]
    if not keys:
        return
    print()
    print("| set | camera | pair (source) | mean flow (px) | shipped EPE | candidate EPE | change "
          "| shipped s40+ | candidate s40+ |")
    print("|---|---|---|---|---|---|---|---|---|")
    fmt = lambda v: "–" if v is None else f"{v:.2f}"
    for key in keys:
        theirs = {r[0]: r for r in ship[key]}
        for name, source, mean_gt, c, c_fast in cand[key]:
            if name not in theirs:
                continue
            s, s_fast = theirs[name][3], theirs[name][4]
            change = f"{(c - s) / s:+.1%}" if s > 0 else ""
            print(f"| {key[0]} | {key[1]} | {name} ({source}) | {mean_gt:.1f} | {s:.3f} | {c:.3f} "
                  f"| {change} | {fmt(s_fast)} | {fmt(c_fast)} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("candidate", help="bench-real report.json of the candidate weights")
    ap.add_argument("shipped", help="bench-real report.json of the shipped weights")
    ap.add_argument("--s12", nargs="*", default=[], help="detect-limits report.json files")
    ap.add_argument("--tolerance", type=float, default=0.02,
                    help="largest relative EPE rise allowed on any set (default 0.02)")
    a = ap.parse_args()
    cand_report, ship_report = load(a.candidate), load(a.shipped)
    mc, cand, cand_pool, cand_speed = scores(cand_report, a.candidate)
    ms, ship, ship_pool, ship_speed = scores(ship_report, a.shipped)
    if mc != ms:
        fail(f"the reports score different methods ({mc} against {ms})")
    if set(cand) != set(ship):
        fail(f"the reports hold different sets: {sorted(set(cand) ^ set(ship))}")

    print(f"| set | camera | shipped EPE | candidate EPE | change | within {a.tolerance:.0%} |")
    print("|---|---|---|---|---|---|")
    worse, worse_keys = [], []
    for key in sorted(ship, key=lambda k: (k[1], k[0])):
        s, c = ship[key], cand[key]
        change = (c - s) / s if s > 0 else 0.0
        ok = change <= a.tolerance
        if not ok:
            worse.append(f"{key[0]} {key[1]} {change:+.1%}")
            worse_keys.append(key)
        print(f"| {key[0]} | {key[1]} | {s:.3f} | {c:.3f} | {change:+.1%} | {'yes' if ok else '**no**'} |")
    for cam in sorted(ship_pool):
        if cam in cand_pool:
            s, c = ship_pool[cam], cand_pool[cam]
            print(f"| all known pixels | {cam} | {s:.3f} | {c:.3f} | {(c - s) / s:+.1%} | |")
    # Where the change lies, by ground-truth speed (not part of the rule).
    for cam in sorted(set(ship_speed) & set(cand_speed)):
        s, c = ship_speed[cam], cand_speed[cam]
        for k, name in enumerate(SPEED_CLASSES):
            if s["pixels"][k] and c["pixels"][k]:
                e0, e1 = s["epe"][k], c["epe"][k]
                change = f"{(e1 - e0) / e0:+.1%}" if e0 > 0 else ""
                print(f"| all pixels moving {name} ({s['pixels'][k]}) | {cam} | {e0:.3f} | "
                      f"{e1:.3f} | {change} | |")

    print_pairs(worse_keys, pairs(cand_report, mc), pairs(ship_report, ms))

    misses = []
    for path in a.s12:
        misses += s12_misses(load(path), path)

    reasons = []
    if not cand_pool["camera"] < ship_pool["camera"]:
        reasons.append(
            f"not better over all pixels through the camera "
            f"({cand_pool['camera']:.3f} against {ship_pool['camera']:.3f})"
        )
    if worse:
        reasons.append("sets worse by more than the tolerance: " + ", ".join(worse))
    if misses:
        reasons.append("Note S12 cases not detected: " + ", ".join(misses))
    print()
    print(f"method: {mc}, {ITERS} iterations; Note S12 reports: {len(a.s12)}")
    if reasons:
        print("verdict: does not ship: " + "; ".join(reasons))
        sys.exit(1)
    print("verdict: ships (bench-real and the Note S12 reports given; the tracker's system "
          "test is separate)")


if __name__ == "__main__":
    main()
