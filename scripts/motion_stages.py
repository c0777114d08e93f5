#!/usr/bin/env python3
"""Where along the MMS network a motion is lost (Notes S9–S11): for each pair of a dataset folder
whose true flow is one translation (`scripts/shift_pairs.py`), how much the features change, where
the first correlation window's peak lies, and how far the first update moves the flow.

    scripts/motion_stages.py --weights W.safetensors --data DIR

Per pair, three numbers in full-resolution pixels along x (medians over the interior cells):
  feature change    ||f2 - f1|| / ||f1|| of the feature encoder's maps (no unit);
  correlation peak  the sub-cell peak of the level-0 window at zero flow, by a parabola through
                    the centre and its two x-neighbours, times 8 (a parabola under-reads a broad
                    peak, so it rises with the motion without equalling it);
  first update      the mean ΔF of the first ConvGRU update from zero flow, times 8.
A motion the features and the correlation carry but the first update does not is lost in the
update block (what its training taught it), not in the encoder.

Needs torch and the PyTorch port (`python/pins_mms`; `pip install -e python`).
"""

import argparse
import glob
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "python"))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--weights", required=True)
    ap.add_argument("--data", required=True)
    a = ap.parse_args()
    try:
        import torch
        from pins_mms import WeightsError, load
        from pins_mms.corr import corr_lookup, corr_pyramid
        from pins_mms.io import read_flo, read_image
        from pins_mms.model import coordinate_grid
    except ImportError as e:
        sys.exit(f"motion_stages: needs torch and python/pins_mms ({e})")
    flows = sorted(glob.glob(os.path.join(a.data, "*_flow.flo")))
    if not flows:
        sys.exit(f"motion_stages: {a.data} holds no *_flow.flo")
    try:
        model = load(a.weights)
    except (WeightsError, ValueError, OSError) as e:
        sys.exit(f"motion_stages: {e}")
    cfg, r = model.config, model.config.corr_radius
    torch.set_grad_enabled(False)

    def frame(path):
        t = torch.from_numpy(read_image(path))[None]  # [1, 3, H, W]
        h, w = t.shape[2] // 8 * 8, t.shape[3] // 8 * 8
        if h < cfg.min_side or w < cfg.min_side:
            sys.exit(f"motion_stages: {path} is smaller than the network's {cfg.min_side} px")
        return t[:, :, :h, :w]

    print("| true motion (px) | feature change | correlation peak (px) | first update (px) |")
    print("|---|---|---|---|")
    for f in flows:
        stem = f[: -len("_flow.flo")]
        try:
            truth = read_flo(f)  # [2, H, W]
            img1, img2 = frame(stem + "_img1.png"), frame(stem + "_img2.png")
        except ValueError as e:
            sys.exit(f"motion_stages: {e}")
        if img1.shape != img2.shape:
            sys.exit(f"motion_stages: {stem}: the two frames differ in size")
        u, v = np.median(truth[0]), np.median(truth[1])
        features = model.feature_encoder(torch.cat([img1, img2], 0) * 2.0 - 1.0)
        f1, f2 = features[:1], features[1:]  # [1, C, H/8, W/8]
        change = ((f2 - f1).norm() / f1.norm()).item()
        pyramid = corr_pyramid(f1, f2, cfg.corr_levels)
        _, _, h8, w8 = f1.shape
        coords0 = coordinate_grid(1, h8, w8, f1.device, f1.dtype)
        window = corr_lookup(pyramid, coords0, r)  # [1, levels·(2r+1)², H/8, W/8]
        k = 2 * r + 1
        level0 = window[0, : k * k].reshape(k, k, h8, w8)[:, :, 4:-4, 4:-4]
        left, centre, right = level0[r, r - 1], level0[r, r], level0[r, r + 1]
        peak = ((right - left) / (2 * (2 * centre - left - right))).median().item() * 8
        context = model.context_encoder(img1 * 2.0 - 1.0)
        hidden = torch.tanh(context[:, : cfg.hidden_dim])
        context = torch.relu(context[:, cfg.hidden_dim :])
        _, delta = model.update(hidden, context, window, coords0 - coords0)
        step = 8 * delta[0, 0, 4:-4, 4:-4].mean().item()
        print(f"| ({u:+.3f}, {v:+.3f}) | {change:.4f} | {peak:+.3f} | {step:+.3f} |")


if __name__ == "__main__":
    main()
