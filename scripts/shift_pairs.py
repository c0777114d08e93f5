#!/usr/bin/env python3
"""Pairs of one real photograph moved by exact sub-pixel translations, as a `pins generate`
dataset folder (NNNNN_img1.png, NNNNN_img2.png, NNNNN_flow.flo), for `pins eval --data` and
`scripts/flow_response.py`: the simplest motion a flow method must report, on real texture,
without the camera.

Frame 2 is frame 1 moved by (du, dv) with the Fourier shift theorem (exact for a band-limited
image; no interpolation blur, which would tell the two frames apart), so the true flow is
(du, dv) at every pixel. The shift wraps around the frame, so both frames are cropped by a
margin (at least 16 px and the largest shift) that holds the wrapped border and the ringing of
the frame's edges; what is left is the pair. Both are rounded to 8 bits as a camera writes them.

    scripts/shift_pairs.py IMAGE --out DIR [--shifts 0.125,0.25,0.5,1,2,4] [--angle DEG]

One pair per shift, moved along --angle degrees from +x (0: right; image y points down).
Needs numpy, and Pillow or OpenCV (cv2) for reading and writing PNGs.
"""

import argparse
import math
import os
import sys

import numpy as np


def write_flo(path, flow):
    """A Middlebury .flo file of the (H, W, 2) float32 flow."""
    h, w, _ = flow.shape
    with open(path, "wb") as f:
        np.array([202021.25], np.float32).tofile(f)
        np.array([w, h], np.int32).tofile(f)
        flow.astype(np.float32).tofile(f)


def image_io():
    """(read, write) of 8-bit RGB arrays (H, W, 3) by Pillow, else OpenCV; None if neither."""
    try:
        from PIL import Image

        def read(path):
            try:
                with Image.open(path) as im:
                    return np.asarray(im.convert("RGB"))
            except OSError:
                return None

        def write(path, a):
            try:
                Image.fromarray(a, "RGB").save(path)
                return True
            except OSError:
                return False

        return read, write
    except ImportError:
        pass
    try:
        import cv2
    except ImportError:
        return None

    def read(path):
        a = cv2.imread(path, cv2.IMREAD_COLOR)
        return None if a is None else a[..., ::-1]

    def write(path, a):
        return cv2.imwrite(path, np.ascontiguousarray(a[..., ::-1]))

    return read, write


def shifted(img, du, dv):
    """`img` (H, W, C) moved by (du, dv) px, periodically: out(x) = img(x − d)."""
    h, w = img.shape[:2]
    fy = np.fft.fftfreq(h)[:, None]
    fx = np.fft.fftfreq(w)[None, :]
    phase = np.exp(-2j * np.pi * (fx * du + fy * dv))
    return np.stack(
        [np.real(np.fft.ifft2(np.fft.fft2(img[..., c]) * phase)) for c in range(img.shape[2])],
        axis=-1,
    )


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("image")
    ap.add_argument("--out", required=True)
    ap.add_argument("--shifts", default="0.125,0.25,0.5,1,2,4")
    ap.add_argument("--angle", type=float, default=0.0)
    a = ap.parse_args()
    io = image_io()
    if io is None:
        sys.exit("shift_pairs: needs Pillow or OpenCV to read and write PNGs (pip install pillow)")
    read, write = io
    try:
        shifts = [float(s) for s in a.shifts.split(",")]
    except ValueError:
        sys.exit(f"shift_pairs: --shifts must be numbers separated by commas, got {a.shifts!r}")
    if not shifts or any(not math.isfinite(s) for s in shifts):
        sys.exit(f"shift_pairs: --shifts must be finite numbers, got {a.shifts!r}")
    img = read(a.image)
    if img is None:
        sys.exit(f"shift_pairs: cannot read {a.image} as an image")
    margin = max(16, math.ceil(max(abs(s) for s in shifts)) + 8)
    h, w = img.shape[:2]
    if h <= 2 * margin + 16 or w <= 2 * margin + 16:
        sys.exit(f"shift_pairs: {a.image} ({w}x{h}) is too small for a {margin} px margin")
    if os.path.exists(a.out) and os.listdir(a.out):
        sys.exit(f"shift_pairs: {a.out} exists and is not empty")
    os.makedirs(a.out, exist_ok=True)
    src = img.astype(np.float64)
    crop = (slice(margin, h - margin), slice(margin, w - margin))
    c, s = math.cos(math.radians(a.angle)), math.sin(math.radians(a.angle))
    for i, d in enumerate(shifts):
        du, dv = d * c, d * s
        second = shifted(src, du, dv)
        stem = os.path.join(a.out, f"{i:05d}")
        for name, frame in (("img1", src), ("img2", second)):
            q = np.clip(np.round(frame[crop]), 0, 255).astype(np.uint8)
            if not write(f"{stem}_{name}.png", q):
                sys.exit(f"shift_pairs: cannot write {stem}_{name}.png")
        ch, cw = h - 2 * margin, w - 2 * margin
        flow = np.empty((ch, cw, 2), np.float32)
        flow[..., 0], flow[..., 1] = du, dv
        write_flo(f"{stem}_flow.flo", flow)
        print(f"{stem}: shift ({du:.4f}, {dv:.4f}) px, {cw}x{ch}")


if __name__ == "__main__":
    main()
