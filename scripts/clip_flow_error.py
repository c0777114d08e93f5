#!/usr/bin/env python3
"""Flow error on a trajectory clip's movers and on its still background (Movies S1-S2's
scenes): for each flow folder given, against the clip's exact flows, the end-point error over
the moving pixels (exact |flow| > 0.5 px) and over the still ones, and the median share of the
true motion the flow finds on the movers (its projection on the true vector over the true
length, per frame). With --dis, OpenCV's DIS (medium and fast presets) on the same frames.

    python3 scripts/clip_flow_error.py CLIP [FLOWS ...] [--dis] [--stride 3]

CLIP is a `pins track render` folder (frames/, flows/); each FLOWS is a folder of .flo files
named as CLIP/flows (e.g. from `pins infer --frames CLIP/frames --out FLOWS`).
"""
import argparse
import os
import sys

import numpy as np


def read_flo(path):
    with open(path, "rb") as f:
        data = f.read()
    if len(data) < 12 or data[:4] != b"PIEH":
        raise ValueError(f"{path}: not a Middlebury .flo file")
    w, h = (int(v) for v in np.frombuffer(data[4:12], np.int32))
    if len(data) != 12 + 8 * w * h:
        raise ValueError(f"{path}: {len(data)} bytes for {w}x{h}")
    return np.frombuffer(data[12:], np.float32).reshape(h, w, 2)


class Score:
    def __init__(self):
        self.mover = [0.0, 0]
        self.still = [0.0, 0]
        self.shares = []

    def add(self, pred, true):
        moving = np.linalg.norm(true, axis=2) > 0.5
        err = np.linalg.norm(pred - true, axis=2)
        self.mover[0] += float(err[moving].sum())
        self.mover[1] += int(moving.sum())
        self.still[0] += float(err[~moving].sum())
        self.still[1] += int((~moving).sum())
        if moving.any():
            t = true[moving]
            length = np.linalg.norm(t, axis=1)
            self.shares.append(float(np.median((pred[moving] * t).sum(1) / length**2)))

    def line(self, name):
        mover = self.mover[0] / max(self.mover[1], 1)
        still = self.still[0] / max(self.still[1], 1)
        share = np.median(self.shares) if self.shares else float("nan")
        return f"{name:24s} movers EPE {mover:6.3f}  still EPE {still:6.3f}  share of motion found {share:5.2f}"


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("clip")
    p.add_argument("flows", nargs="*")
    p.add_argument("--dis", action="store_true", help="also OpenCV DIS medium and fast")
    p.add_argument("--stride", type=int, default=3, help="score every STRIDE-th pair")
    a = p.parse_args()
    names = sorted(f for f in os.listdir(os.path.join(a.clip, "flows")) if f.endswith(".flo"))
    frames = sorted(os.listdir(os.path.join(a.clip, "frames")))
    if not names or len(frames) < len(names) + 1:
        sys.exit(f"{a.clip}: needs flows/*.flo and one more frame than flows")
    scores = {f: Score() for f in a.flows}
    dis = {}
    if a.dis:
        try:
            import cv2
        except ImportError:
            sys.exit("--dis needs OpenCV (pip install opencv-python-headless)")
        cv2.setNumThreads(1)
        for preset in ("medium", "fast"):
            dis[f"DIS {preset}"] = (
                cv2.DISOpticalFlow_create(getattr(cv2, f"DISOPTICAL_FLOW_PRESET_{preset.upper()}")),
                Score(),
            )
    for n in range(0, len(names), max(a.stride, 1)):
        true = read_flo(os.path.join(a.clip, "flows", names[n]))
        for f in a.flows:
            scores[f].add(read_flo(os.path.join(f, names[n])), true)
        if dis:
            import cv2

            grey = [
                cv2.cvtColor(cv2.imread(os.path.join(a.clip, "frames", frames[k])), cv2.COLOR_BGR2GRAY)
                for k in (n, n + 1)
            ]
            for method, score in dis.values():
                score.add(method.calc(grey[0], grey[1], None), true)
    for f in a.flows:
        print(scores[f].line(os.path.basename(os.path.normpath(f))))
    for name, (_, score) in dis.items():
        print(score.line(name))


if __name__ == "__main__":
    main()
