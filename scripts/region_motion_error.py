#!/usr/bin/env python3
"""Region motion error of a tracking run (Note S13's regions against a rendered clip's truth).

For every accepted region in `pins track --debug DIR`'s regions.jsonl whose flow centroid lies
within 1.2 radii of a true object centre (and has at least --min-area pixels), compares the
region's mean flow and, where the alignment ran, its aligned motion (`aligned`) with the
object's true displacement to the next frame (truth.json of `pins track render`): the error's
size, and its signed part along the true motion (the speed found minus the true speed, over
displacements of at least 0.5 px; negative: the motion falls short), in px and as a share of the
true speed.

    python3 scripts/region_motion_error.py CLIP/truth.json DEBUG_DIR [--min-area 300]
"""
import argparse
import json
import math
import sys


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("truth", help="truth.json of pins track render")
    ap.add_argument("debug", help="folder with regions.jsonl (pins track --debug)")
    ap.add_argument("--min-area", type=int, default=300)
    a = ap.parse_args()
    try:
        truth = json.load(open(a.truth))
        lines = open(f"{a.debug}/regions.jsonl").read().splitlines()
    except (OSError, ValueError) as e:
        sys.exit(f"region_motion_error: {e}")
    flow_err, aligned_err, with_aligned = [], [], 0
    flow_along, aligned_along = [], []
    for line in lines:
        d = json.loads(line)
        f = d["frame"]
        for r in d["regions"]:
            if not r["accepted"] or r["area"] < a.min_area:
                continue
            cx, cy = r["centroid"]
            best = None
            for ob in truth["objects"]:
                cs = ob["centroids"]
                if f + 1 < len(cs) and cs[f] and cs[f + 1]:
                    dist = math.hypot(cs[f][0] - cx, cs[f][1] - cy)
                    if dist < 1.2 * ob["radius"] and (best is None or dist < best[0]):
                        best = (dist, cs[f], cs[f + 1])
            if best is None:
                continue
            tx, ty = best[2][0] - best[1][0], best[2][1] - best[1][1]
            fx, fy = r["mean_flow"]
            ax, ay = r.get("aligned") or r["mean_flow"]
            with_aligned += "aligned" in r
            flow_err.append(math.hypot(fx - tx, fy - ty))
            aligned_err.append(math.hypot(ax - tx, ay - ty))
            speed = math.hypot(tx, ty)
            if speed >= 0.5:
                ux, uy = tx / speed, ty / speed
                flow_along.append((fx * ux + fy * uy - speed, speed))
                aligned_along.append((ax * ux + ay * uy - speed, speed))
    if not flow_err:
        sys.exit("region_motion_error: no accepted region lies on an object")

    def stats(v):
        v = sorted(v)
        return "mean %.2f median %.2f p90 %.2f" % (
            sum(v) / len(v),
            v[len(v) // 2],
            v[min(len(v) - 1, int(0.9 * len(v)))],
        )

    print(f"regions on objects: {len(flow_err)}, aligned: {with_aligned}")
    print(f"mean flow error (px): {stats(flow_err)}")
    print(f"motion used error (px): {stats(aligned_err)}")

    def along(v):
        if not v:
            return "no displacement of 0.5 px or more"
        return "mean %+.2f px (%+.1f %% of the true speed) over %d" % (
            sum(e for e, _ in v) / len(v),
            100 * sum(e for e, _ in v) / sum(s for _, s in v),
            len(v),
        )

    print(f"mean flow along the true motion: {along(flow_along)}")
    print(f"motion used along the true motion: {along(aligned_along)}")


if __name__ == "__main__":
    main()
