#!/usr/bin/env python3
"""The whole system's targets on many clips (Table S5 at twice the paper's error,
docs/tracking.md): reads the evals.jsonl files that
scripts/track_system_sweep.sh writes and prints, per clip and over all, what
tests/track_system.rs asserts and what it reports.

Single discs pass with one track on the disc, no ID switch, nothing missed and RMSE_2D one
frame ahead within the target (sinusoid 3.7, spiral 12, random path 22 px). Five discs are
"followed" when every disc has a track, none is missed and no track follows nothing; they are
within every five-object target when also at most 2 ID switches and every ID within 23 px one
frame ahead.

    scripts/track_system_summary.py OUT/evals.jsonl [MORE.jsonl ...]
"""

import json
import math
import sys

TARGET = {"sinusoid": 3.7, "spiral": 12.0, "random": 22.0}
HORIZONS = (1, 15, 30)


def pooled(report, horizon):
    for h in report["overall"]:
        if h["horizon"] == horizon and h["rmse_2d"] is not None:
            return h["rmse_2d"]
    return math.nan


def geomean(values):
    values = [v for v in values if v == v and v > 0]
    if not values:
        return math.nan
    return math.exp(sum(math.log(v) for v in values) / len(values))


def main(paths):
    if not paths:
        sys.exit(__doc__)
    reports = {}
    for path in paths:
        with open(path) as f:
            for n, line in enumerate(f, 1):
                if not line.strip():
                    continue
                try:
                    d = json.loads(line)
                    reports[d["name"]] = d["eval"]
                except (ValueError, KeyError) as e:
                    sys.exit(f"{path}:{n}: not a sweep line ({e})")
    singles = passed = five = followed_all = within = switches = 0
    by_kind = {}
    fails = []
    for name in sorted(reports, key=lambda s: (int(s.rsplit("_", 1)[1]), s)):
        r = reports[name]
        kind = name.rsplit("_", 1)[0]
        p = [pooled(r, h) for h in HORIZONS]
        by_kind.setdefault(kind, []).append(p)
        errors = " / ".join(f"{v:.2f}" if i == 0 else f"{v:.1f}" for i, v in enumerate(p))
        if kind in TARGET:
            singles += 1
            ok = (
                len(r["objects"]) == 1
                and r["objects"][0]["truth_index"] == 0
                and r["id_switches"] == 0
                and not r["missed"]
                and p[0] <= TARGET[kind]
            )
            passed += ok
            if not ok:
                fails.append(name)
            print(
                f"{name:14s} {len(r['objects'])} track(s), {r['id_switches']} switches, "
                f"missed {r['missed']}, RMSE_2D {errors} px: {'pass' if ok else 'FAIL'}"
            )
        else:
            five += 1
            false = sum(
                1 for o in r["objects"] if o["truth_index"] is None and o.get("second_on") is None
            )
            ones = [
                h["rmse_2d"]
                for o in r["objects"]
                if o["truth_index"] is not None
                for h in o["horizons"]
                if h["horizon"] == 1 and h["rmse_2d"] is not None
            ]
            worst = max(ones) if ones else math.nan
            discs = {o["truth_index"] for o in r["objects"] if o["truth_index"] is not None}
            ok = len(discs) == 5 and not r["missed"] and false == 0
            tgt = ok and r["id_switches"] <= 2 and worst <= 23.0
            followed_all += ok
            within += tgt
            switches += r["id_switches"]
            if not ok:
                fails.append(name)
            print(
                f"{name:14s} {len(r['objects'])} tracks ({false} on nothing), "
                f"{r['id_switches']} switches, missed {r['missed']}, worst ID {worst:.1f} px, "
                f"pooled {errors} px: {'followed' if ok else 'FAIL'}"
                f"{', within every target' if tgt else ''}"
            )
    print(f"single discs passing: {passed} of {singles}")
    print(
        f"five discs all followed with no track on nothing: {followed_all} of {five}; "
        f"within every five-object target: {within} of {five}; ID switches {switches}"
    )
    for kind, rows in by_kind.items():
        g = [geomean([row[i] for row in rows]) for i in range(len(HORIZONS))]
        print(f"{kind}: {len(rows)} clips, geometric mean RMSE_2D 1 / 15 / 30 frames ahead "
              f"{g[0]:.2f} / {g[1]:.1f} / {g[2]:.1f} px")
    print("failing:", " ".join(fails) if fails else "none")


if __name__ == "__main__":
    main(sys.argv[1:])
