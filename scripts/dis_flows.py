#!/usr/bin/env python3
"""OpenCV's DIS flow between each consecutive pair of a folder of frames, written as Middlebury
.flo files (00000.flo: frame 0 to 1, ...), the peer of `pins infer --frames` for `pins track
--flows`:

    python3 scripts/dis_flows.py --frames CLIP/frames --out CLIP/dis_medium [--preset medium]

DIS runs on the frames' luma with one thread, as in scripts/flow_baselines.py.
"""
import argparse
import os
import sys
import time

import numpy as np


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--frames", required=True)
    p.add_argument("--out", required=True)
    p.add_argument("--preset", default="medium", choices=["ultrafast", "fast", "medium"])
    a = p.parse_args()
    try:
        import cv2
    except ImportError:
        sys.exit("needs OpenCV: pip install opencv-python-headless")
    cv2.setNumThreads(1)
    names = sorted(f for f in os.listdir(a.frames) if f.lower().endswith((".png", ".jpg", ".jpeg", ".ppm", ".tif", ".tiff")))
    if len(names) < 2:
        sys.exit(f"{a.frames}: needs at least two frames")
    dis = cv2.DISOpticalFlow_create(getattr(cv2, f"DISOPTICAL_FLOW_PRESET_{a.preset.upper()}"))

    def grey(name):
        img = cv2.imread(os.path.join(a.frames, name))
        if img is None:
            sys.exit(f"{name}: not a readable image")
        return cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)

    tmp = a.out + ".part"
    os.makedirs(tmp, exist_ok=True)
    prev = grey(names[0])
    calc_s = 0.0
    for n in range(len(names) - 1):
        cur = grey(names[n + 1])
        if cur.shape != prev.shape:
            sys.exit(f"{names[n + 1]}: {cur.shape} differs from the frame before, {prev.shape}")
        started = time.perf_counter()
        flow = dis.calc(prev, cur, None)
        calc_s += time.perf_counter() - started
        flow = flow.astype(np.float32)
        h, w = flow.shape[:2]
        with open(os.path.join(tmp, f"{n:05d}.flo"), "wb") as f:
            f.write(b"PIEH" + np.array([w, h], np.int32).tobytes() + flow.tobytes())
        prev = cur
    if os.path.exists(a.out):
        sys.exit(f"{a.out} exists: give a new folder (the flows are in {tmp})")
    os.rename(tmp, a.out)
    pairs = len(names) - 1
    print(f"{pairs} flows in {a.out}; DIS {1e3 * calc_s / pairs:.3f} ms per pair")


if __name__ == "__main__":
    main()
