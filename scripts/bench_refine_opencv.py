#!/usr/bin/env python3
"""OpenCV's VariationalRefinement timed on the pair `pins bench-flow --mode refine --pair-out DIR`
wrote (frame1.png, frame2.png, start.flo, truth.flo), with the settings of pins' defaults
(alpha 20, delta 5, gamma 10, 5 fixed-point iterations of 5 SOR sweeps, omega 1.9; OpenCV's
own omega is 1.6, and it has no local smoothness weight, pins' kappa) at full resolution only (OpenCV's refinement has no pyramid). Prints one JSON line like pins': median ms
over --reps runs after a warm-up, and the end-point error before and after (pixels at least 8 px
from the border).

Usage: python3 scripts/bench_refine_opencv.py --pair DIR [--reps 5] [--threads 2]
"""
import argparse
import json
import sys
import time


def read_flo(path):
    import numpy as np
    with open(path, "rb") as f:
        if np.fromfile(f, np.float32, 1)[0] != 202021.25:
            raise SystemExit(f"{path}: not a .flo file")
        w, h = np.fromfile(f, np.int32, 2)
        data = np.fromfile(f, np.float32, 2 * w * h)
    if data.size != 2 * w * h:
        raise SystemExit(f"{path}: truncated")
    return data.reshape(h, w, 2)


def epe(flow, truth):
    import numpy as np
    d = (flow - truth)[8:-8, 8:-8]
    return float(np.sqrt((d ** 2).sum(-1)).mean())


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pair", required=True, help="folder written by --pair-out")
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--threads", type=int, default=2)
    a = ap.parse_args()
    if a.reps < 1:
        raise SystemExit("--reps must be positive")
    import cv2
    import numpy as np
    cv2.setNumThreads(a.threads)
    i0 = cv2.imread(f"{a.pair}/frame1.png", cv2.IMREAD_GRAYSCALE)
    i1 = cv2.imread(f"{a.pair}/frame2.png", cv2.IMREAD_GRAYSCALE)
    if i0 is None or i1 is None:
        raise SystemExit(f"cannot read frame1.png / frame2.png in {a.pair}")
    start = read_flo(f"{a.pair}/start.flo")
    truth = read_flo(f"{a.pair}/truth.flo")
    vr = cv2.VariationalRefinement_create()
    vr.setAlpha(20.0)
    vr.setDelta(5.0)
    vr.setGamma(10.0)
    vr.setFixedPointIterations(5)
    vr.setSorIterations(5)
    vr.setOmega(1.9)

    def once():
        flow = start.copy()
        vr.calc(i0, i1, flow)
        return flow

    refined = once()
    times = []
    for _ in range(a.reps):
        t = time.perf_counter()
        once()
        times.append(1e3 * (time.perf_counter() - t))
    times.sort()
    h, w = i0.shape
    print(json.dumps({
        "tool": f"opencv {cv2.__version__} VariationalRefinement", "mode": "refine",
        "height": h, "width": w, "threads": cv2.getNumThreads(), "scales": [1],
        "ms": times[len(times) // 2], "epe_start": epe(start, truth),
        "epe_refined": epe(refined, truth),
    }))


if __name__ == "__main__":
    sys.exit(main())
