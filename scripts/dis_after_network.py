#!/usr/bin/env python3
"""OpenCV DIS's patch search after the network: does it add sub-pixel precision to MMS's flow?

For every pair of each dataset folder (NNNNN_img1.png, NNNNN_img2.png, NNNNN_flow.flo, as
`pins generate` and `pins bench-real` write them) it runs `pins infer` (the flow commands'
defaults: coarse start, variational refinement, 12 iterations; cached in --work), then DIS
medium at full and half resolution (finest scale 0, coarsest 1) from the first frame to the
second warped back by that flow (bicubic), and composes the
two (f(x + r(x)) + r(x)). It prints, per folder and over all pixels, the EPE and the share
within 1 px of MMS, of DIS medium alone and of MMS followed by DIS. DIS runs on luma, one thread,
as in scripts/flow_baselines.py.

    scripts/dis_after_network.py --pins PINS --work out/dis_after DIR [DIR ...] [--weights W]

Needs numpy and OpenCV (opencv-python-headless).
"""

import argparse
import glob
import os
import subprocess
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from flow_response import read_flo  # noqa: E402


def write_flo(path, flow):
    h, w = flow.shape[:2]
    with open(path, "wb") as f:
        np.array([202021.25], "<f4").tofile(f)
        np.array([w, h], "<i4").tofile(f)
        flow.astype("<f4").tofile(f)


def dis(cv2, a, b, fine=False):
    """DIS medium; `fine`: its search and refinement at full and half resolution only (the
    residual motion is small, and full resolution is where the precision is)."""
    d = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)
    if fine:
        d.setFinestScale(0)
        d.setCoarsestScale(1)
    return d.calc(a, b, None)


def after(cv2, a, b, est):
    """DIS on the residual motion left by `est`, composed with it."""
    h, w = a.shape
    xx, yy = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    b_back = cv2.remap(b, xx + est[..., 0], yy + est[..., 1], cv2.INTER_CUBIC,
                       borderMode=cv2.BORDER_REPLICATE)
    r = dis(cv2, a, b_back, fine=True)
    moved = [cv2.remap(np.ascontiguousarray(est[..., k]), xx + r[..., 0], yy + r[..., 1],
                       cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE) for k in range(2)]
    return np.dstack(moved) + r


def errors(est, truth):
    ok = (np.abs(truth[..., 0]) < 1e9) & (np.abs(truth[..., 1]) < 1e9)
    return np.hypot(*(est - truth)[ok].T)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("dirs", nargs="+")
    p.add_argument("--pins", required=True, help="the pins binary")
    p.add_argument("--work", required=True, help="folder for the network's flows (reused)")
    p.add_argument("--weights", default="default")
    a = p.parse_args()
    try:
        import cv2
    except ImportError:
        sys.exit("dis_after_network: needs OpenCV: pip install opencv-python-headless")
    cv2.setNumThreads(1)
    methods = ["MMS", "DIS medium", "MMS, then DIS medium"]
    pooled = {m: [] for m in methods}
    print("| data | pairs | " + " | ".join(f"{m} EPE, 1 px" for m in methods) + " |")
    print("|---|---|" + "---|" * len(methods))
    for d in a.dirs:
        pairs = sorted(glob.glob(os.path.join(d, "*_img1.png")))
        if not pairs:
            sys.exit(f"dis_after_network: {d} holds no NNNNN_img1.png")
        tag = os.path.basename(os.path.normpath(d))
        os.makedirs(os.path.join(a.work, tag), exist_ok=True)
        errs = {m: [] for m in methods}
        for img1 in pairs:
            stem = img1[: -len("_img1.png")]
            name = os.path.basename(stem)
            truth = read_flo(stem + "_flow.flo").astype(np.float64)
            mms_path = os.path.join(a.work, tag, name + "_mms.flo")
            if not os.path.exists(mms_path):
                run = subprocess.run([a.pins, "infer", "--weights", a.weights, "--img1", img1,
                                      "--img2", stem + "_img2.png", "--out", mms_path],
                                     capture_output=True, text=True)
                if run.returncode != 0:
                    sys.exit(f"dis_after_network: pins infer failed on {img1}: {run.stderr.strip()}")
            est = read_flo(mms_path).astype(np.float32)
            i1 = cv2.imread(img1, cv2.IMREAD_GRAYSCALE)
            i2 = cv2.imread(stem + "_img2.png", cv2.IMREAD_GRAYSCALE)
            if i1 is None or i2 is None:
                sys.exit(f"dis_after_network: cannot read the frames of {stem}")
            for m, flow in [("MMS", est), ("DIS medium", dis(cv2, i1, i2)),
                            ("MMS, then DIS medium", after(cv2, i1, i2, est))]:
                e = errors(flow.astype(np.float64), truth)
                errs[m].append(e)
                pooled[m].append(e)
        cells = []
        for m in methods:
            e = np.concatenate(errs[m])
            cells.append(f"{e.mean():.3f}, {np.mean(e < 1):.3f}")
        print(f"| {tag} | {len(pairs)} | " + " | ".join(cells) + " |")
    cells = []
    for m in methods:
        e = np.concatenate(pooled[m])
        cells.append(f"{e.mean():.3f}, {np.mean(e < 1):.3f}")
    print("| all known pixels | | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
