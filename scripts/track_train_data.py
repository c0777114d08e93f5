#!/usr/bin/env python3
"""Training pairs from random trajectory clips (Movies S1-S2's scenes): discs of random size,
path, speed and start moving over the camera's still background, rendered through the metalens
camera by `pins track render`, each consecutive frame pair with its exact flow linked into one
FlyingChairs-named folder (NNNNN_img1.png, NNNNN_img2.png, NNNNN_flow.flo) for `pins train`.

    python3 scripts/track_train_data.py --pins PINS --out DIR [--clips 80] [--frames 40] [--seed 1000]

Clip k uses scene seed SEED + k; the tracking experiments' clips use seeds below 100, so a
SEED of 1000 or more keeps every training clip apart from them.
"""
import argparse
import json
import os
import random
import shutil
import subprocess
import sys


def clip_config(rng, seed, frames):
    objects = []
    for _ in range(rng.randint(1, 6)):
        path = rng.choice(["sinusoid", "spiral", "random", "line", "line"])
        o = {
            "path": path,
            "radius": round(rng.uniform(6.0, 24.0), 1),
            "start": round(rng.uniform(0.0, 4.0), 2),
            "rate": round(rng.uniform(0.5, 2.5), 2),
        }
        if path == "line":
            # From one side of the frame (or just outside it) to another.
            a = [rng.uniform(-0.1, 1.1), rng.uniform(-0.1, 1.1)]
            b = [rng.uniform(-0.1, 1.1), rng.uniform(-0.1, 1.1)]
            o["from"], o["to"] = [round(v, 3) for v in a], [round(v, 3) for v in b]
            o["start"], o["rate"] = 0.0, round(rng.uniform(0.3, 1.5), 2)
        objects.append(o)
    return {
        "scene": {
            "width": 640,
            "height": 480,
            "fps": 30,
            "frames": frames,
            "seed": seed,
            "objects": objects,
        }
    }


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--pins", required=True, help="the pins binary")
    p.add_argument("--out", required=True, help="output folder of pairs (must not exist)")
    p.add_argument("--clips", type=int, default=80)
    p.add_argument("--frames", type=int, default=40)
    p.add_argument("--seed", type=int, default=1000)
    a = p.parse_args()
    if a.clips < 1 or a.frames < 2:
        sys.exit("--clips must be at least 1 and --frames at least 2")
    if os.path.exists(a.out):
        sys.exit(f"{a.out} exists: give a new folder")
    work = a.out + ".clips"
    os.makedirs(work, exist_ok=True)
    rng = random.Random(a.seed)
    pairs = []
    for k in range(a.clips):
        seed = a.seed + k
        cfg = os.path.join(work, f"clip{seed}.json")
        with open(cfg, "w") as f:
            json.dump(clip_config(rng, seed, a.frames), f, indent=1)
        clip = os.path.join(work, f"clip{seed}")
        r = subprocess.run(
            [a.pins, "track", "render", "--config", cfg, "--out", clip],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
        )
        if r.returncode != 0:
            sys.exit(f"rendering {cfg} failed: {r.stderr.strip()}")
        frames = sorted(os.listdir(os.path.join(clip, "frames")))
        flows = sorted(os.listdir(os.path.join(clip, "flows")))
        for n, flow in enumerate(flows):
            pairs.append(
                (
                    os.path.join(clip, "frames", frames[n]),
                    os.path.join(clip, "frames", frames[n + 1]),
                    os.path.join(clip, "flows", flow),
                )
            )
    tmp = a.out + ".part"
    shutil.rmtree(tmp, ignore_errors=True)
    os.makedirs(tmp)
    for i, (img1, img2, flow) in enumerate(pairs):
        for src, name in ((img1, "img1.png"), (img2, "img2.png"), (flow, "flow.flo")):
            os.link(src, os.path.join(tmp, f"{i:05d}_{name}"))
    os.rename(tmp, a.out)
    print(f"{len(pairs)} pairs from {a.clips} clips in {a.out}")


if __name__ == "__main__":
    main()
