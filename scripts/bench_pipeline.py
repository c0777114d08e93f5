#!/usr/bin/env python3
"""The pins camera model in numpy/scipy, timed the same way as `pins bench`, for a ratio
measured on one machine in one run.

Chain per 3-channel frame: brightness x 0.8 -> mirrored-border PSF convolution with
scipy.signal.fftconvolve (per channel) -> Gaussian noise N(y, a*y + b) in 8-bit DN ->
clamp -> gamma 1.7 -> 8-bit quantisation. Also times the convolution alone over PSF sizes.

Usage: python3 scripts/bench_pipeline.py [--json out.json] [--reps 5]
Run with one thread for a per-core comparison: OMP_NUM_THREADS=1 (numpy's FFT is single
threaded anyway).
"""
import argparse
import json
import os
import statistics
import sys
import time

import numpy as np
from scipy.signal import fftconvolve

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def load_psf():
    return np.load(os.path.join(ROOT, "datasets", "psf", "metalens_default.npy")).astype(np.float32)


def crop_kernel(psf, k):
    c, h, w = psf.shape
    out = np.zeros((k, k), np.float32)
    for y in range(k):
        for x in range(k):
            sy, sx = y - k // 2 + h // 2, x - k // 2 + w // 2
            if 0 <= sy < h and 0 <= sx < w:
                out[y, x] = psf[1, sy, sx]
    return out / out.sum(dtype=np.float64)


def blur(plane, kernel):
    r = kernel.shape[0] // 2
    padded = np.pad(plane, r, mode="reflect")  # numpy 'reflect' = no edge repeat, as pins
    return fftconvolve(padded, kernel, mode="valid")


def camera(frame, psf, rng, a=0.2, b=10.0, gamma=1.7):
    y = frame * np.float32(0.8)
    y = np.stack([blur(y[c], psf[c]) for c in range(3)]).astype(np.float32)
    dn = np.maximum(y, 0) * 255.0
    z = dn + np.sqrt(a * dn + b) * rng.standard_normal(dn.shape, dtype=np.float32)
    z = np.clip(z / 255.0, 0.0, 1.0)
    z = np.power(z, gamma)
    return np.round(z * 255.0) / 255.0


def median_ms(reps, f):
    f()
    times = []
    for _ in range(reps):
        t = time.perf_counter()
        f()
        times.append((time.perf_counter() - t) * 1e3)
    return statistics.median(times)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--json")
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--psf-sizes", default="9,17,33,65,129")
    args = ap.parse_args()
    psf = load_psf()
    rng = np.random.default_rng(1)
    pipeline = []
    for h, w in [(384, 512), (480, 1440)]:
        frame = rng.random((3, h, w), dtype=np.float32)
        ms = median_ms(args.reps, lambda: camera(frame, psf, rng))
        pipeline.append({"height": h, "width": w, "threads": 1, "ms_per_frame": ms, "pairs_per_s": 1e3 / (2 * ms)})
    plane = rng.random((384, 512), dtype=np.float32)
    conv = []
    for k in [int(s) for s in args.psf_sizes.split(",")]:
        kern = crop_kernel(psf, k)
        conv.append({"psf_size": k, "fft_ms": median_ms(args.reps, lambda: blur(plane, kern))})
    report = {"tool": f"numpy {np.__version__}, scipy {__import__('scipy').__version__}",
              "pipeline": pipeline, "convolution": conv}
    for r in pipeline:
        print(f"numpy/scipy {r['height']}x{r['width']}x3: {r['ms_per_frame']:.1f} ms per frame")
    for r in conv:
        print(f"numpy/scipy fftconvolve {r['psf_size']}x{r['psf_size']} on 384x512: {r['fft_ms']:.1f} ms")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(report, f, indent=2)


if __name__ == "__main__":
    sys.exit(main())
