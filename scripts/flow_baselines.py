#!/usr/bin/env python3
"""Classical optical-flow baselines (OpenCV) scored on a `pins generate` dataset, with the
same metrics as the Rust side (`src/flow/metrics.rs`), for the peers table.

Methods: OpenCV DIS optical flow with presets MEDIUM, FAST and ULTRAFAST, and Farneback with
OpenCV's usual parameters (pyr_scale 0.5, levels 3, winsize 15, iterations 3, poly_n 5,
poly_sigma 1.2, flags 0). Each runs on every pair NNNNN_img1.png / NNNNN_img2.png, read as
8-bit colour with cv2.imread and converted to grey with cv2.cvtColor(COLOR_RGB2GRAY), and is
scored against NNNNN_flow.flo (Middlebury .flo; u = +x right, v = +y down).

Metrics, as sums over the valid pixels of all pairs divided by their total count (a mean over
pixels, not a mean of per-image means):
  epe     mean ||pred - gt||
  ae_deg  mean angle in degrees between (u, v, 1) and (ug, vg, 1) (Baker et al. 2011), with
          the cosine clamped to [-1, 1]
  px1/3/5 fraction of pixels with end-point error < 1, 3, 5 px
  by_speed {"pixels": [n, n, n], "epe": [e, e, e]}: the EPE over the pixels whose ground-truth
          speed is below 10 px, from 10 to below 40, and 40 or more (MPI-Sintel's s0-10,
          s10-40, s40+; 0 where a class has no pixel)
A pixel is valid when both ground-truth components are finite and below 1e9 in magnitude
(Middlebury's unknown-flow marker).

Timing: per method, one untimed warm-up call on the first pair, then every pair is timed
(the flow call only, on the already grey images); ms_per_pair = total time / pairs.
cv2.setNumThreads(--threads) is set before anything runs.

Each method's scores are also given per pair (the pair's name is its NNNNN stem; ms is that
pair's time), and the zero-flow baseline is scored the same way (its EPE is the mean ground-truth
speed over the valid pixels, given per pair as mean_gt).

Usage:
  python3 scripts/flow_baselines.py --data out/eval_data [--out peers.json] [--threads 1]
      [--flows DIR]   # also each method's flow: DIR/dis_medium/NNNNN.flo, ... (Middlebury .flo)
Needs: python3 -m pip install -r python/requirements-peers.txt (the OpenCV of the reports)

Output JSON (`pins eval --peers` reads methods[].name, .epe and .ms_per_pair; `pins bench-real`
reads the rest):
  {"data": "...", "pairs": N, "opencv": "4.x", "threads": 1,
   "methods": [{"name": "OpenCV DIS medium", "epe": .., "ae_deg": .., "px1": .., "px3": ..,
                "px5": .., "by_speed": {..}, "ms_per_pair": ..,
                "per_pair": [{"name": "00000", "pixels": .., "epe": .., "ae_deg": .., "px1": ..,
                              "px3": .., "px5": .., "by_speed": {..}, "ms": ..}, ...]}, ...],
   "zero_flow": {same fields as a method, ms 0; per_pair also has mean_gt}}
"""
import argparse
import glob
import json
import os
import re
import sys
import time

try:
    import numpy as np
except ImportError:
    sys.exit("error: numpy is not installed (pip install numpy)")
try:
    import cv2
except ImportError:
    sys.exit("error: OpenCV is not installed (pip install opencv-python-headless)")

FLO_MAGIC = 202021.25
UNKNOWN_THRESHOLD = 1e9
# Ground-truth speeds (px) that open MPI-Sintel's classes s10-40 and s40+ (metrics.rs).
SPEED_CLASS_EDGES = [10.0, 40.0]


class DataError(Exception):
    pass


def read_flo(path):
    """Reads a Middlebury .flo file into an (H, W, 2) float32 array; unknown vectors
    (|component| >= 1e9) become NaN."""
    try:
        raw = open(path, "rb").read()
    except OSError as e:
        raise DataError(f"cannot read {path}: {e}") from e
    if len(raw) < 12:
        raise DataError(f"{path}: {len(raw)} bytes, too short for a .flo header (12 bytes)")
    magic = np.frombuffer(raw, dtype="<f4", count=1, offset=0)[0]
    if magic != np.float32(FLO_MAGIC):
        raise DataError(f"{path}: bad .flo magic {magic!r} (expected {FLO_MAGIC})")
    w, h = (int(x) for x in np.frombuffer(raw, dtype="<i4", count=2, offset=4))
    if w <= 0 or h <= 0:
        raise DataError(f"{path}: bad .flo size {w}x{h}")
    expected = 12 + 8 * w * h
    if len(raw) != expected:
        raise DataError(f"{path}: a {w}x{h} field needs {expected} bytes, found {len(raw)}")
    flow = np.frombuffer(raw, dtype="<f4", count=2 * w * h, offset=12).reshape(h, w, 2).astype(np.float32)
    unknown = (np.abs(flow) >= UNKNOWN_THRESHOLD).any(axis=2)
    flow[unknown] = np.nan
    return flow


def read_grey(path):
    """8-bit colour image -> 8-bit grey, via RGB2GRAY on the RGB channel order."""
    img = cv2.imread(path, cv2.IMREAD_COLOR)
    if img is None:
        raise DataError(f"cv2.imread could not read {path} (missing or not an image)")
    if img.dtype != np.uint8:
        raise DataError(f"{path}: expected an 8-bit image, got {img.dtype}")
    rgb = cv2.cvtColor(img, cv2.COLOR_BGR2RGB)  # imread gives BGR
    return cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)


def find_pairs(data):
    if not os.path.isdir(data):
        raise DataError(f"--data {data}: not a directory")
    pairs = []
    for img1 in sorted(glob.glob(os.path.join(data, "*_img1.png"))):
        stem = img1[: -len("_img1.png")]
        if not re.fullmatch(r"\d+", os.path.basename(stem)):
            continue
        img2, flo = stem + "_img2.png", stem + "_flow.flo"
        for p in (img2, flo):
            if not os.path.isfile(p):
                raise DataError(f"{img1} has no partner {os.path.basename(p)}")
        pairs.append((os.path.basename(stem), img1, img2, flo))
    if not pairs:
        raise DataError(f"no NNNNN_img1.png / NNNNN_img2.png / NNNNN_flow.flo triples in {data}")
    return pairs


def load_pairs(pairs):
    out = []
    for name, img1, img2, flo in pairs:
        g1, g2, gt = read_grey(img1), read_grey(img2), read_flo(flo)
        if g1.shape != g2.shape:
            raise DataError(f"{img1} is {g1.shape[1]}x{g1.shape[0]} but {img2} is {g2.shape[1]}x{g2.shape[0]}")
        if gt.shape[:2] != g1.shape:
            raise DataError(f"{flo} is {gt.shape[1]}x{gt.shape[0]} but {img1} is {g1.shape[1]}x{g1.shape[0]}")
        out.append((name, g1, g2, gt))
    return out


class Sums:
    """Running sums over valid pixels, as FlowErrorSums on the Rust side."""

    def __init__(self):
        self.pixels = 0
        self.epe = 0.0
        self.ae = 0.0
        self.w1 = self.w3 = self.w5 = 0
        self.class_pixels = [0, 0, 0]
        self.class_epe = [0.0, 0.0, 0.0]

    def add(self, pred, gt, where):
        if pred.shape != gt.shape:
            raise DataError(f"{where}: predicted flow {pred.shape} vs ground truth {gt.shape}")
        gu, gv = gt[..., 0].astype(np.float64), gt[..., 1].astype(np.float64)
        valid = np.isfinite(gu) & np.isfinite(gv)
        u, v = pred[..., 0].astype(np.float64)[valid], pred[..., 1].astype(np.float64)[valid]
        gu, gv = gu[valid], gv[valid]
        if not (np.isfinite(u).all() and np.isfinite(v).all()):
            raise DataError(f"{where}: the method returned non-finite flow vectors")
        e = np.sqrt((u - gu) ** 2 + (v - gv) ** 2)
        cos = (u * gu + v * gv + 1.0) / np.sqrt((u * u + v * v + 1.0) * (gu * gu + gv * gv + 1.0))
        ae = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
        self.pixels += int(e.size)
        self.epe += float(e.sum())
        self.ae += float(ae.sum())
        self.w1 += int((e < 1.0).sum())
        self.w3 += int((e < 3.0).sum())
        self.w5 += int((e < 5.0).sum())
        cls = np.searchsorted(SPEED_CLASS_EDGES, np.sqrt(gu * gu + gv * gv), side="right")
        for c in range(3):
            self.class_pixels[c] += int((cls == c).sum())
            self.class_epe[c] += float(e[cls == c].sum())

    def merge(self, o):
        self.pixels += o.pixels
        self.epe += o.epe
        self.ae += o.ae
        self.w1 += o.w1
        self.w3 += o.w3
        self.w5 += o.w5
        for c in range(3):
            self.class_pixels[c] += o.class_pixels[c]
            self.class_epe[c] += o.class_epe[c]

    def scores(self):
        n = max(self.pixels, 1)
        by_speed = {"pixels": list(self.class_pixels),
                    "epe": [e / max(k, 1) for e, k in zip(self.class_epe, self.class_pixels)]}
        return {"epe": self.epe / n, "ae_deg": self.ae / n,
                "px1": self.w1 / n, "px3": self.w3 / n, "px5": self.w5 / n, "by_speed": by_speed}


def dis_method(preset):
    dis = cv2.DISOpticalFlow_create(preset)
    return lambda a, b: dis.calc(a, b, None)


def farneback(a, b):
    return cv2.calcOpticalFlowFarneback(a, b, None, 0.5, 3, 15, 3, 5, 1.2, 0)


METHODS = [
    ("OpenCV DIS medium", lambda: dis_method(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)),
    ("OpenCV DIS fast", lambda: dis_method(cv2.DISOPTICAL_FLOW_PRESET_FAST)),
    ("OpenCV DIS ultrafast", lambda: dis_method(cv2.DISOPTICAL_FLOW_PRESET_ULTRAFAST)),
    ("OpenCV Farneback", lambda: farneback),
]


def slug(name):
    """A method's folder under --flows: "OpenCV DIS medium" -> "dis_medium"."""
    return re.sub(r"[^a-z0-9]+", "_", name.lower().removeprefix("opencv ")).strip("_")


def write_flo(path, flow):
    """Writes (H, W, 2) flow as a Middlebury .flo file, all or nothing."""
    h, w = flow.shape[:2]
    tmp = f"{path}.tmp{os.getpid()}"
    with open(tmp, "wb") as f:
        f.write(np.array([FLO_MAGIC], "<f4").tobytes())
        f.write(np.array([w, h], "<i4").tobytes())
        f.write(np.ascontiguousarray(flow, "<f4").tobytes())
    os.replace(tmp, path)


def run_method(name, make, data, flows=None):
    fn = make()
    fn(data[0][1], data[0][2])  # untimed warm-up
    sums, seconds, per_pair = Sums(), 0.0, []
    for pair, g1, g2, gt in data:
        t0 = time.perf_counter()
        pred = fn(g1, g2)
        dt = time.perf_counter() - t0
        seconds += dt
        if pred is None:
            raise DataError(f"{name}: no flow returned for pair {pair}")
        if flows:
            d = os.path.join(flows, slug(name))
            try:
                os.makedirs(d, exist_ok=True)
                write_flo(os.path.join(d, f"{pair}.flo"), np.asarray(pred, dtype=np.float32))
            except OSError as e:
                raise DataError(f"--flows {flows}: cannot write {name}'s flow of pair {pair}: {e}")
        one = Sums()
        one.add(np.asarray(pred, dtype=np.float32), gt, f"{name}, pair {pair}")
        sums.merge(one)
        per_pair.append({"name": pair, "pixels": one.pixels, **one.scores(), "ms": 1e3 * dt})
    return {"name": name, **sums.scores(), "ms_per_pair": 1e3 * seconds / len(data),
            "per_pair": per_pair}


def zero_flow(data):
    """The zero-flow baseline; its per-pair EPE is the mean ground-truth speed (mean_gt)."""
    sums, per_pair = Sums(), []
    for pair, g1, _, gt in data:
        one = Sums()
        one.add(np.zeros(gt.shape, dtype=np.float32), gt, f"zero flow, pair {pair}")
        sums.merge(one)
        s = one.scores()
        per_pair.append({"name": pair, "pixels": one.pixels, "mean_gt": s["epe"], **s, "ms": 0.0})
    return {"name": "zero flow", **sums.scores(), "ms_per_pair": 0.0, "per_pair": per_pair}


def table(rows):
    s = "| method | EPE | AE (deg) | <1px | <3px | <5px | ms/pair |\n"
    s += "|---|---|---|---|---|---|---|\n"
    for r in rows:
        s += (f"| {r['name']} | {r['epe']:.3f} | {r['ae_deg']:.2f} | {r['px1']:.3f} | "
              f"{r['px3']:.3f} | {r['px5']:.3f} | {r['ms_per_pair']:.1f} |\n")
    return s


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", required=True, help="folder written by `pins generate`")
    ap.add_argument("--out", help="write the JSON here (default: print only the table)")
    ap.add_argument("--threads", type=int, default=1, help="cv2.setNumThreads (default 1)")
    ap.add_argument("--flows", help="also write each method's flow here: DIR/METHOD/NNNNN.flo")
    args = ap.parse_args()
    if args.threads < 0:
        ap.error("--threads must be >= 0")
    cv2.setNumThreads(args.threads)
    try:
        data = load_pairs(find_pairs(args.data))
        h, w = data[0][1].shape
        print(f"{len(data)} pairs ({w}x{h}) from {args.data}; OpenCV {cv2.__version__}, "
              f"{cv2.getNumThreads()} thread(s)", file=sys.stderr)
        rows = [run_method(name, make, data, args.flows) for name, make in METHODS]
        zero = zero_flow(data)
    except DataError as e:
        sys.exit(f"error: {e}")
    print(table(rows + [zero]), end="")
    if args.out:
        doc = {"data": args.data, "pairs": len(data), "opencv": cv2.__version__,
               "threads": cv2.getNumThreads(), "methods": rows, "zero_flow": zero}
        try:
            d = os.path.dirname(os.path.abspath(args.out))
            os.makedirs(d, exist_ok=True)
            tmp = f"{args.out}.tmp{os.getpid()}"
            with open(tmp, "w") as f:
                json.dump(doc, f, indent=2)
                f.write("\n")
            os.replace(tmp, args.out)  # all or nothing
        except OSError as e:
            sys.exit(f"error: cannot write {args.out}: {e}")
        print(f"wrote {args.out}", file=sys.stderr)


if __name__ == "__main__":
    main()
