#!/usr/bin/env python3
"""CPU time and peak memory of torchvision's RAFT (raft_small / raft_large), for comparison
with `pins bench-flow` on the same machine. One measurement per process, so that the peak
RSS printed belongs to that measurement alone (scripts/bench_flow_compare.sh runs them all).

Models: torchvision.models.optical_flow.raft_small / raft_large with weights=None (random
init, torch.manual_seed(0)); only speed and memory are measured, never accuracy.
torch.set_num_threads(--threads, default 2).

Modes:
  infer  one pair (batch 1) of random images at --height x --width, 12 flow updates
         (num_flow_updates=12), model.eval() under torch.inference_mode(); one untimed
         warm-up, then the median of --reps runs.
  train  one training step: batch --batch (2) of random --height x --width images (use
         128x128) and a random flow target, 12 updates, model.train(); RAFT's sequence loss
         sum_i 0.8^(n-1-i) * mean|flow_i - target| over all n predictions (L1, every pixel
         valid); AdamW lr 4e-4 (torch's other defaults); zero_grad + forward + loss +
         backward + optimizer step are timed. One untimed warm-up step, then the median of
         --reps steps.

Height and width must be multiples of 8 (RAFT works at 1/8 resolution).

Usage:
  python3 scripts/bench_raft.py --model raft_small|raft_large --mode infer|train \
      --height H --width W --reps N [--threads 2] [--batch 2]
Prints one JSON line on stdout:
  {"tool": "torchvision raft_small", "mode": "infer", "height": H, "width": W, "iters": 12,
   "ms": median_ms, "peak_rss_mb": ..., "params": n_params}
peak_rss_mb is getrusage(RUSAGE_SELF).ru_maxrss (KiB on Linux) / 1024, for the whole process
(it includes the Python interpreter and the torch libraries: about 690 MB right after
`import torch, torchvision` with the CUDA-bundled PyPI wheels of torch 2.15; that figure is
printed on stderr).
Needs: pip install torch torchvision (the PyPI Linux wheels bundle CUDA; they run on CPU).
"""
import argparse
import json
import resource
import statistics
import sys
import time

ITERS = 12
GAMMA = 0.8
LR = 4e-4


def sequence_loss(preds, target, gamma=GAMMA):
    n = len(preds)
    loss = 0.0
    for i, p in enumerate(preds):
        loss = loss + gamma ** (n - 1 - i) * (p - target).abs().mean()
    return loss


def peak_rss_mb():
    kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    if sys.platform == "darwin":  # bytes there
        kb /= 1024
    return kb / 1024


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--model", required=True, choices=["raft_small", "raft_large"])
    ap.add_argument("--mode", required=True, choices=["infer", "train"])
    ap.add_argument("--height", type=int, required=True)
    ap.add_argument("--width", type=int, required=True)
    ap.add_argument("--reps", type=int, default=3, help="timed runs after one warm-up (median)")
    ap.add_argument("--threads", type=int, default=2, help="torch.set_num_threads (default 2)")
    ap.add_argument("--batch", type=int, default=2, help="training batch size (default 2)")
    args = ap.parse_args()
    for name in ("height", "width"):
        v = getattr(args, name)
        if v < 16 or v % 8:
            ap.error(f"--{name} {v}: must be a multiple of 8 and at least 16")
    if args.reps < 1:
        ap.error("--reps must be >= 1")
    if args.threads < 1:
        ap.error("--threads must be >= 1")
    if args.batch < 1:
        ap.error("--batch must be >= 1")

    try:
        import torch
        from torchvision.models import optical_flow
    except ImportError as e:
        sys.exit(f"error: {e} (pip install torch torchvision)")
    torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    print(f"torch {torch.__version__}, {torch.get_num_threads()} thread(s), {args.model} {args.mode} "
          f"{args.height}x{args.width}, {args.reps} rep(s); peak RSS after importing torch: "
          f"{peak_rss_mb():.0f} MB", file=sys.stderr)

    try:
        model = getattr(optical_flow, args.model)(weights=None, progress=False)
    except Exception as e:  # noqa: BLE001 - report any construction failure plainly
        sys.exit(f"error: could not build torchvision {args.model}: {e}")
    n_params = sum(p.numel() for p in model.parameters())
    h, w = args.height, args.width
    times = []

    if args.mode == "infer":
        model.eval()
        img1 = torch.rand(1, 3, h, w) * 2 - 1  # RAFT expects [-1, 1]
        img2 = torch.rand(1, 3, h, w) * 2 - 1
        with torch.inference_mode():
            model(img1, img2, num_flow_updates=ITERS)  # warm-up
            for _ in range(args.reps):
                t0 = time.perf_counter()
                preds = model(img1, img2, num_flow_updates=ITERS)
                times.append(time.perf_counter() - t0)
        if len(preds) != ITERS or tuple(preds[-1].shape) != (1, 2, h, w):
            sys.exit(f"error: unexpected RAFT output: {len(preds)} predictions, last {tuple(preds[-1].shape)}")
    else:
        model.train()
        b = args.batch
        img1 = torch.rand(b, 3, h, w) * 2 - 1
        img2 = torch.rand(b, 3, h, w) * 2 - 1
        target = torch.randn(b, 2, h, w) * 5
        opt = torch.optim.AdamW(model.parameters(), lr=LR)

        def step():
            opt.zero_grad(set_to_none=True)
            preds = model(img1, img2, num_flow_updates=ITERS)
            loss = sequence_loss(preds, target)
            loss.backward()
            opt.step()
            return float(loss.detach())

        step()  # warm-up
        for _ in range(args.reps):
            t0 = time.perf_counter()
            loss = step()
            times.append(time.perf_counter() - t0)
        if loss != loss:  # NaN
            sys.exit("error: training loss is NaN")

    print(json.dumps({
        "tool": f"torchvision {args.model}",
        "mode": args.mode,
        "height": h,
        "width": w,
        "iters": ITERS,
        "ms": 1e3 * statistics.median(times),
        "peak_rss_mb": round(peak_rss_mb(), 1),
        "params": n_params,
    }))


if __name__ == "__main__":
    main()
