#!/usr/bin/env python3
"""Which stage of the camera makes the flow fail on a pair: the pair regenerated with each stage
of the camera undone in turn, every weights' flow on each, and the EPE over all pixels and over
the pixels moving 40 px or more (Sintel's s40+).

DATA is a dataset folder `pins generate` or `pins bench-real` wrote (its `config.json` and the
pairs `NNNNN_img1.png`, `NNNNN_img2.png`, `NNNNN_flow.flo`). Its config is written again under
--work once as it is (the same seed: the same images and noise) and once per variant:

  camera       the folder's camera as it is
  no noise     Poisson-Gaussian noise with a = b = 0
  delta PSF    no blur
  gamma 1      a linear response
  brightness 1 no light loss
  PSF only     brightness 1, gamma 1, no noise: the blur alone

and `pins infer` (the flow commands' defaults: coarse start, variational refinement, 12
iterations) runs each weights on each pair. One row per variant, pair and weights:

    scripts/camera_stages.py --pins PINS --work out/stages DATA --pairs 00002 \\
        --weights datasets/weights/mms-small-real.safetensors experiments/campaign/cooldown.safetensors

Needs numpy.
"""

import argparse
import copy
import json
import os
import subprocess
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from flow_response import read_flo  # noqa: E402

FAST = 40.0


def variants(camera):
    """(name, camera config) for the folder's camera and each stage undone."""
    def edit(**changes):
        c = copy.deepcopy(camera)
        for key, value in changes.items():
            if key == "noise":
                if c.get("noise") is None:
                    return None
                c["noise"] = dict(c["noise"], a=0.0, b=0.0)
            else:
                c[key] = value
        return c

    out = [
        ("camera", copy.deepcopy(camera)),
        ("no noise", edit(noise=True)),
        ("delta PSF", edit(psf="delta")),
        ("gamma 1", edit(gamma=1.0)),
        ("brightness 1", edit(brightness=1.0)),
        ("PSF only", edit(noise=True, gamma=1.0, brightness=1.0)),
    ]
    return [(n, c) for n, c in out if c is not None]


def scene_path(scene, data):
    """A dataset scene's `path` made absolute: as written, else from the working directory's
    repository root, else from the folder."""
    path = scene.get("path")
    if path is None or os.path.isabs(path):
        return scene
    for base in (os.getcwd(), os.path.join(os.getcwd(), "experiments"), data):
        candidate = os.path.normpath(os.path.join(base, path))
        if os.path.isdir(candidate):
            return dict(scene, path=candidate)
    sys.exit(f"camera_stages: {data}/config.json: scene path {path} not found")


def errors(est, truth):
    e = np.linalg.norm(est - truth, axis=2)
    fast = np.linalg.norm(truth, axis=2) >= FAST
    return float(e.mean()), (float(e[fast].mean()) if fast.any() else None)


def run(cmd):
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"camera_stages: {' '.join(cmd)} failed:\n{done.stderr.strip()}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("data", help="a dataset folder with config.json")
    ap.add_argument("--pins", default="pins")
    ap.add_argument("--work", required=True, help="folder for the variants and the flows")
    ap.add_argument("--pairs", nargs="+", required=True, help="pair names (00002 ...)")
    ap.add_argument("--weights", nargs="+", default=["default"])
    a = ap.parse_args()
    try:
        with open(os.path.join(a.data, "config.json")) as f:
            config = json.load(f)
    except (OSError, json.JSONDecodeError) as e:
        sys.exit(f"camera_stages: {a.data}: {e}")
    if "camera" not in config or "scene" not in config:
        sys.exit(f"camera_stages: {a.data}/config.json has no camera or scene")
    try:
        count = max(int(p) for p in a.pairs) + 1
    except ValueError:
        sys.exit(f"camera_stages: pair names are numbers (00002), not {a.pairs}")
    config["scene"] = scene_path(config["scene"], a.data)
    config["count"] = count

    print(f"| variant | pair | weights | EPE | EPE s{FAST:.0f}+ |")
    print("|---|---|---|---|---|")
    for k, (name, camera) in enumerate(variants(config["camera"])):
        folder = os.path.join(a.work, f"v{k}")
        os.makedirs(folder, exist_ok=True)
        cfg = os.path.join(a.work, f"v{k}.json")
        with open(cfg, "w") as f:
            json.dump(dict(config, camera=camera), f)
        run([a.pins, "generate", "--config", cfg, "--out", folder, "--quiet"])
        for pair in a.pairs:
            truth = read_flo(os.path.join(folder, f"{pair}_flow.flo"))
            for w, weights in enumerate(a.weights):
                flo = os.path.join(a.work, f"v{k}-{pair}-w{w}.flo")
                run([a.pins, "infer", "--weights", weights,
                     "--img1", os.path.join(folder, f"{pair}_img1.png"),
                     "--img2", os.path.join(folder, f"{pair}_img2.png"), "--out", flo])
                epe, fast = errors(read_flo(flo), truth)
                fast = "–" if fast is None else f"{fast:.2f}"
                print(f"| {name} | {pair} | {os.path.basename(weights)} | {epe:.3f} | {fast} |",
                      flush=True)


if __name__ == "__main__":
    main()
