#!/usr/bin/env python3
"""Region motion error of a tracking run (Note S13's regions against a rendered clip's truth).

For every accepted region in `pins track --debug DIR`'s regions.jsonl whose flow centroid lies
within 1.2 radii of a true object centre (and has at least --min-area pixels), compares the
region's mean flow and, where the alignment ran, its aligned motion (`aligned`) with the
object's true displacement to the next frame (truth.json of `pins track render`).

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


if __name__ == "__main__":
    main()
