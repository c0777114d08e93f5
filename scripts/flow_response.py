#!/usr/bin/env python3
"""How much of the true motion a flow estimate reports, by the size of the motion.

An estimate that shrinks small motions toward zero has a low EPE on still scenes and a poor one
on scenes of sub-pixel and pixel motion (Middlebury): this separates the two. For every band of
true motion length it prints the pixels, the EPE and the median of the estimate's component
along the true motion over the true length (1: the whole motion, 0: none); then the
least-squares slope of each estimated component on the true one (1 for an unbiased estimate).
Each band also has the share of its pixels within 1 px and its median end-point error: where a
method loses the 1-px share (gross errors at one motion size, or a spread at all of them).

    scripts/flow_response.py EST.flo:TRUTH.flo [EST2.flo:TRUTH2.flo ...]   # pooled over pairs
    scripts/flow_response.py --data DIR [--every N]   # a dataset's true motions: still share, bands

Middlebury .flo files only (unknown flow, |u| or |v| >= 1e9, is left out). numpy only.
"""

import argparse
import glob
import os
import sys

import numpy as np

BANDS = [(0.05, 0.5), (0.5, 1.0), (1.0, 2.0), (2.0, 4.0), (4.0, 8.0), (8.0, 16.0), (16.0, 32.0),
         (32.0, 64.0), (64.0, np.inf)]


def read_flo(path):
    """The (H, W, 2) float32 flow of a Middlebury .flo file; exits with the reason if it is not one."""
    try:
        raw = open(path, "rb").read()
    except OSError as e:
        sys.exit(f"flow_response: cannot read {path}: {e}")
    if len(raw) < 12 or np.frombuffer(raw[:4], "<f4")[0] != 202021.25:
        sys.exit(f"flow_response: {path} is not a .flo file (no 202021.25 tag)")
    w, h = (int(v) for v in np.frombuffer(raw[4:12], "<i4"))
    if w <= 0 or h <= 0 or len(raw) != 12 + w * h * 8:
        sys.exit(f"flow_response: {path}: {w}x{h} does not match its {len(raw)} bytes")
    return np.frombuffer(raw[12:], "<f4").reshape(h, w, 2)


def band_name(lo, hi):
    return f"{lo:g}–{hi:g} px" if np.isfinite(hi) else f"≥ {lo:g} px"


def response(pairs):
    est, truth = [], []
    for spec in pairs:
        if ":" not in spec:
            sys.exit(f"flow_response: expected EST.flo:TRUTH.flo, got {spec}")
        e_path, t_path = spec.rsplit(":", 1)
        e, t = read_flo(e_path), read_flo(t_path)
        if e.shape != t.shape:
            sys.exit(f"flow_response: {e_path} is {e.shape[1]}x{e.shape[0]}, {t_path} {t.shape[1]}x{t.shape[0]}")
        known = (np.isfinite(t) & (np.abs(t) < 1e9)).all(-1)
        est.append(e[known])
        truth.append(t[known])
    e, t = np.concatenate(est).astype(np.float64), np.concatenate(truth).astype(np.float64)
    length = np.linalg.norm(t, axis=1)
    print(f"{len(pairs)} pair(s), {len(t)} known pixels, EPE {np.linalg.norm(e - t, axis=1).mean():.3f}")
    print("| true motion | pixels | EPE | within 1 px | median error | along the truth / true length (median) |")
    print("|---|---|---|---|---|---|")
    for lo, hi in BANDS:
        sel = (length >= lo) & (length < hi)
        if sel.sum() == 0:
            continue
        along = (e[sel] * t[sel]).sum(1) / length[sel] ** 2
        err = np.linalg.norm(e[sel] - t[sel], axis=1)
        print(f"| {band_name(lo, hi)} | {sel.sum()} | {err.mean():.3f} | {(err < 1.0).mean():.3f} | "
              f"{np.median(err):.2f} | {np.median(along):.2f} |")
    for c, name in ((0, "u"), (1, "v")):
        if np.ptp(t[:, c]) == 0:
            # One true value (a pure translation): no slope to fit.
            print(f"{name}: true {t[0, c]:+.3f} px everywhere, estimate mean {e[:, c].mean():+.3f} px")
            continue
        a = np.vstack([t[:, c], np.ones(len(t))]).T
        slope, offset = np.linalg.lstsq(a, e[:, c], rcond=None)[0]
        corr = np.corrcoef(t[:, c], e[:, c])[0, 1] if np.ptp(e[:, c]) > 0 else float("nan")
        print(f"{name}: slope {slope:.2f}, offset {offset:+.3f} px, correlation {corr:.2f}")


def dataset(root, every):
    files = sorted(glob.glob(os.path.join(root, "*_flow.flo")))[::every]
    if not files:
        sys.exit(f"flow_response: {root} holds no *_flow.flo")
    flows = [read_flo(f).reshape(-1, 2) for f in files]
    # Shares of the known pixels (KITTI's sparse truth marks the rest unknown).
    lengths = np.concatenate([np.linalg.norm(f[(np.isfinite(f) & (np.abs(f) < 1e9)).all(-1)], axis=-1) for f in flows])
    shares = [f"still {(lengths < 0.05).mean():.2f}"]
    shares += [f"{band_name(lo, hi)} {((lengths >= lo) & (lengths < hi)).mean():.2f}" for lo, hi in BANDS]
    print(f"{root}: {len(files)} pairs; share of pixels: " + ", ".join(shares))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("pairs", nargs="*", help="EST.flo:TRUTH.flo")
    ap.add_argument("--data", nargs="+", help="dataset folders (pins generate): their true motions")
    ap.add_argument("--every", type=int, default=1, help="with --data: every Nth pair")
    a = ap.parse_args()
    if a.every < 1:
        sys.exit("flow_response: --every must be at least 1")
    if a.data:
        for d in a.data:
            dataset(d, a.every)
    if a.pairs:
        response(a.pairs)
    if not a.data and not a.pairs:
        ap.error("give EST.flo:TRUTH.flo pairs or --data DIR")


if __name__ == "__main__":
    main()
