"""Command line: `python -m pins_mms infer` (the network's flow for one pair, from PyTorch or an
ONNX file), `python -m pins_mms export` (a weights file to ONNX) and `python -m pins_mms bench`
(the network's time on one pair)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m pins_mms", description=__doc__)
    sub = p.add_subparsers(dest="command", required=True)
    i = sub.add_parser("infer", help="the network's flow for one pair, written as .flo "
                       "(pins infer --start zero --refine none)")
    i.add_argument("--weights", default="default", help="pins weights file, or default / mms-small")
    i.add_argument("--onnx", help="run this ONNX file (python -m pins_mms export) with ONNX Runtime instead")
    i.add_argument("--img1", required=True)
    i.add_argument("--img2", required=True)
    i.add_argument("--out", required=True, help="output .flo")
    i.add_argument("--iters", type=int, help="refinements (default: the weights' own)")
    i.add_argument("--device", default="cpu", help="torch device: cpu, cuda, cuda:1, ...")
    e = sub.add_parser("export", help="export a weights file to ONNX")
    e.add_argument("weights", help="pins weights file, or default / mms-small")
    e.add_argument("--out", required=True, help="output .onnx")
    e.add_argument("--iters", type=int, help="refinements, fixed in the graph (default: the weights' own)")
    e.add_argument("--size", help="WxH: a fixed input size instead of any size")
    e.add_argument("--opset", type=int, default=18)
    bn = sub.add_parser("bench", help="time the network on one pair of random images (the "
                        "counterpart of pins bench-flow --mode infer); one JSON line")
    bn.add_argument("--weights", default="default", help="pins weights file, or default / mms-small")
    bn.add_argument("--height", type=int, default=368)
    bn.add_argument("--width", type=int, default=496)
    bn.add_argument("--iters", type=int, default=12)
    bn.add_argument("--reps", type=int, default=3)
    bn.add_argument("--device", default="cpu")
    bn.add_argument("--onnx", help="time this ONNX file by ONNX Runtime instead (CPU, or CUDA "
                    "where onnxruntime-gpu is installed)")
    args = p.parse_args(argv)
    try:
        if args.command == "infer":
            return infer(args)
        if args.command == "bench":
            return bench(args)
        return export(args)
    except (ValueError, OSError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2


def infer(args) -> int:
    import numpy as np

    from .io import read_image, write_flo

    out = Path(args.out)
    if out.suffix.lower() != ".flo":
        raise ValueError(f"--out {out}: expected a .flo file")
    a, b = read_image(args.img1), read_image(args.img2)
    if a.shape != b.shape:
        raise ValueError(f"second image is {b.shape[2]}x{b.shape[1]}, the first {a.shape[2]}x{a.shape[1]}")
    if args.onnx:
        from .onnx_export import run_onnx

        if args.iters is not None:
            raise ValueError("--iters: an ONNX graph's iteration count is fixed at its export")
        providers = ["CUDAExecutionProvider"] if args.device.startswith("cuda") else None
        flow = run_onnx(args.onnx, a[None], b[None], providers)[0]
    else:
        import torch

        from .model import FlowModel
        from .weights import load

        if args.iters is not None and not 1 <= args.iters <= 256:
            raise ValueError(f"--iters must be 1..=256, got {args.iters}")
        model = FlowModel(load(args.weights, args.device), args.iters)
        with torch.inference_mode():
            t = lambda x: torch.from_numpy(x[None]).to(args.device)
            flow = model(t(a), t(b))[0].cpu().numpy()
    if not np.isfinite(flow).all():
        raise ValueError("the network produced non-finite flow")
    write_flo(out, flow)
    return 0


def export(args) -> int:
    from .onnx_export import export_onnx

    size = None
    if args.size:
        try:
            w, h = (int(v) for v in args.size.lower().split("x"))
        except ValueError:
            raise ValueError(f"--size {args.size!r}: expected WxH, e.g. 640x480") from None
        size = (h, w)
    export_onnx(args.weights, args.out, args.iters, size, args.opset)
    return 0


def bench(args) -> int:
    """The median of `--reps` runs after one untimed warm-up (kernel selection, allocation)."""
    import json
    import statistics
    import time

    import numpy as np

    if args.reps < 1 or args.iters < 1 or min(args.height, args.width) < 1:
        raise ValueError("--reps, --iters, --height and --width must be positive")
    rng = np.random.default_rng(0)
    a, b = (rng.random((1, 3, args.height, args.width), dtype=np.float32) for _ in range(2))
    if args.onnx:
        import onnxruntime as ort

        from .onnx_export import pad_to_network

        providers = [p for p in ("CUDAExecutionProvider", "CPUExecutionProvider")
                     if p in ort.get_available_providers()]
        session = ort.InferenceSession(args.onnx, providers=providers)
        min_side = int(session.get_modelmeta().custom_metadata_map.get("pins.min_side", "64"))
        feed = {"image1": pad_to_network(a, min_side)[0], "image2": pad_to_network(b, min_side)[0]}
        run = lambda: session.run(["flow"], feed)
        tool, iters = f"onnxruntime {providers[0]}", session.get_modelmeta().custom_metadata_map.get("pins.iters")
    else:
        import torch

        from .model import FlowModel
        from .weights import load

        model = FlowModel(load(args.weights, args.device), args.iters)
        ta, tb = torch.from_numpy(a).to(args.device), torch.from_numpy(b).to(args.device)
        sync = torch.cuda.synchronize if str(args.device).startswith("cuda") else (lambda: None)

        def run():
            with torch.inference_mode():
                model(ta, tb)
            sync()

        tool, iters = f"pins_mms torch {torch.__version__} {args.device}", args.iters
    run()
    times = []
    for _ in range(args.reps):
        t = time.perf_counter()
        run()
        times.append(1000 * (time.perf_counter() - t))
    print(json.dumps({"tool": tool, "height": args.height, "width": args.width, "iters": iters,
                      "ms": round(statistics.median(times), 1), "reps": args.reps}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
