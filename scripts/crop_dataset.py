#!/usr/bin/env python3
"""Cuts fixed-size crops out of a flow dataset (FlyingChairs naming: NNNNN_img1.png,
NNNNN_img2.png, NNNNN_flow.flo) into a new dataset of the same naming, to measure how a flow
method's error depends on the image size it sees.

Each pair gives up to four crops (top-left, bottom-right, centre, top-right; only the centre
when two crops would not fit side by side). The flow is cut, not changed: vectors that leave
the crop stay in the ground truth, as they do for any method run on the crop.

Usage:
  python3 scripts/crop_dataset.py --data out/eval_data --out out/eval_crop_128x160 --size 128 160
Needs: pip install opencv-python-headless numpy
"""
import argparse
import glob
import os
import sys

try:
    import numpy as np
    import cv2
except ImportError:
    sys.exit("error: numpy and OpenCV are needed (pip install numpy opencv-python-headless)")

FLO_MAGIC = 202021.25


def read_flo(path):
    with open(path, "rb") as f:
        magic = np.fromfile(f, np.float32, 1)
        if magic.size != 1 or magic[0] != FLO_MAGIC:
            raise ValueError(f"{path}: not a Middlebury .flo file (bad magic)")
        dims = np.fromfile(f, np.int32, 2)
        if dims.size != 2 or dims[0] <= 0 or dims[1] <= 0:
            raise ValueError(f"{path}: bad size header")
        w, h = int(dims[0]), int(dims[1])
        data = np.fromfile(f, np.float32, 2 * w * h)
        if data.size != 2 * w * h:
            raise ValueError(f"{path}: truncated ({data.size} of {2 * w * h} values)")
    return data.reshape(h, w, 2)


def write_flo(path, flow):
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        np.array([FLO_MAGIC], np.float32).tofile(f)
        np.array([flow.shape[1], flow.shape[0]], np.int32).tofile(f)
        np.ascontiguousarray(flow, dtype=np.float32).tofile(f)
    os.replace(tmp, path)


def write_png(path, img):
    tmp = path + ".tmp.png"
    if not cv2.imwrite(tmp, img):
        raise ValueError(f"cannot write {path}")
    os.replace(tmp, path)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", required=True, help="dataset folder (NNNNN_img1.png, ...)")
    ap.add_argument("--out", required=True, help="new folder for the crops (must not exist)")
    ap.add_argument("--size", required=True, nargs=2, type=int, metavar=("H", "W"))
    a = ap.parse_args()
    h, w = a.size
    if h < 8 or w < 8:
        sys.exit(f"error: --size {h} {w}: both sides must be at least 8")
    flows = sorted(glob.glob(os.path.join(a.data, "*_flow.flo")))
    if not flows:
        sys.exit(f"error: {a.data}: no NNNNN_flow.flo files")
    if os.path.exists(a.out):
        sys.exit(f"error: {a.out} already exists")
    os.makedirs(a.out)
    k = 0
    try:
        for f in flows:
            base = f[: -len("_flow.flo")]
            flow = read_flo(f)
            i1 = cv2.imread(base + "_img1.png", cv2.IMREAD_UNCHANGED)
            i2 = cv2.imread(base + "_img2.png", cv2.IMREAD_UNCHANGED)
            if i1 is None or i2 is None:
                raise ValueError(f"{base}: cannot read _img1.png / _img2.png")
            H, W = flow.shape[:2]
            if i1.shape[:2] != (H, W) or i2.shape[:2] != (H, W):
                raise ValueError(f"{base}: images and flow differ in size")
            if H < h or W < w:
                raise ValueError(f"{base}: {W}x{H} is smaller than the crop {w}x{h}")
            corners = [(0, 0), (H - h, W - w), ((H - h) // 2, (W - w) // 2), (0, W - w)]
            if 2 * h > H or 2 * w > W:
                corners = corners[2:3]
            for y, x in corners:
                name = os.path.join(a.out, f"{k:05d}")
                write_png(name + "_img1.png", i1[y : y + h, x : x + w])
                write_png(name + "_img2.png", i2[y : y + h, x : x + w])
                write_flo(name + "_flow.flo", flow[y : y + h, x : x + w])
                k += 1
    except ValueError as e:
        sys.exit(f"error: {e}")
    print(f"{k} crops of {w}x{h} from {len(flows)} pairs -> {a.out}")


if __name__ == "__main__":
    main()
