"""ONNX export of the network with a fixed iteration count, and its run by ONNX Runtime.

The graph takes `image1`, `image2` `[B, 3, H, W]` in [0, 1] with H and W multiples of 8 (at least
the config's `min_side`, 64 for 4 pyramid levels) and gives `flow` `[B, 2, H, W]` in pixels; H
and W are dynamic unless a size is given. Other sizes are padded by [`pad_to_network`] (edges
replicated, centred: pins's `InputPadder`) and the flow cropped back, as [`run_onnx`] does. The
padding stays outside the graph: traced with symbolic sizes it turns into guards the exporter
cannot prove.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np


def export_onnx(weights: str, out: str | Path, iters: int | None = None,
                size: tuple[int, int] | None = None, opset: int = 18) -> Path:
    """Writes the ONNX graph of a pins weights file to `out` (atomically); `size` (H, W) fixes
    the input size, else any multiple of 8 from `min_side` to 8192 is accepted."""
    import torch

    from .io import publish
    from .weights import load

    out = Path(out)
    if out.suffix.lower() != ".onnx":
        raise ValueError(f"--out {out}: expected a .onnx file")
    mms = load(weights)
    cfg = mms.config
    iters = cfg.iters if iters is None else iters
    if not 1 <= iters <= 64:
        raise ValueError(f"--iters must be 1..=64 in an exported graph, got {iters}")
    if size is not None:
        h, w = size
        if h % 8 or w % 8 or min(h, w) < cfg.min_side:
            raise ValueError(f"size {w}x{h}: sides must be multiples of 8 and at least {cfg.min_side}")
    else:
        h, w = cfg.min_side + 24, cfg.min_side + 40
    class Fixed(torch.nn.Module):
        """The network at a fixed iteration count, as a module of two inputs."""

        def __init__(self):
            super().__init__()
            self.mms = mms

        def forward(self, image1, image2):
            return self.mms(image1, image2, iters)

    model = Fixed().eval()
    example = (torch.rand(1, 3, h, w), torch.rand(1, 3, h, w))
    dynamic = None
    if size is None:
        dim = torch.export.Dim
        h8 = dim("h8", min=cfg.min_side // 8, max=1024)
        w8 = dim("w8", min=cfg.min_side // 8, max=1024)
        dynamic = ({2: 8 * h8, 3: 8 * w8}, {2: 8 * h8, 3: 8 * w8})
    with torch.inference_mode():
        program = torch.export.export(model, example, dynamic_shapes=dynamic, strict=False)
        onnx_program = torch.onnx.export(program, input_names=["image1", "image2"],
                                         output_names=["flow"], opset_version=opset, dynamo=True,
                                         optimize=False)
    # The exporter notes each node's Python stack: 60 % of the file, dropped.
    for node in onnx_program.model.graph:
        node.metadata_props.clear()
        node.doc_string = None
    onnx_program.model.producer_name = "pins_mms"
    onnx_program.model.metadata_props.update({"pins.model_config": cfg.to_json(), "pins.iters": str(iters),
                                              "pins.min_side": str(cfg.min_side)})
    # Written beside the target and renamed: a failed export leaves nothing behind.
    fd, tmp = tempfile.mkstemp(dir=out.parent if str(out.parent) else ".", prefix=".onnx-", suffix=".onnx")
    os.close(fd)
    try:
        onnx_program.save(tmp, external_data=False)
        publish(tmp, out)
    finally:
        Path(tmp).unlink(missing_ok=True)
    return out


def pad_to_network(images: np.ndarray, min_side: int) -> tuple[np.ndarray, tuple[int, int, int, int]]:
    """`[B, C, H, W]` edge-replicated to multiples of 8 at least `min_side`, centred (the odd
    pixel after): the padded array and (top, bottom, left, right)."""
    _, _, h, w = images.shape

    def split(n: int) -> tuple[int, int]:
        total = (max(n, min_side) + 7) // 8 * 8 - n
        return total // 2, total - total // 2

    (top, bottom), (left, right) = split(h), split(w)
    padded = np.pad(images, ((0, 0), (0, 0), (top, bottom), (left, right)), mode="edge")
    return padded, (top, bottom, left, right)


def run_onnx(path: str | Path, image1: np.ndarray, image2: np.ndarray, providers=None) -> np.ndarray:
    """The flow `[B, 2, H, W]` of images `[B, 3, H, W]` in [0, 1] by ONNX Runtime, any size."""
    import onnxruntime as ort

    options = ort.SessionOptions()
    options.log_severity_level = 3  # errors only: the exporter's CastLike nodes are not folded, harmlessly
    session = ort.InferenceSession(str(path), options, providers=providers or ["CPUExecutionProvider"])
    meta = session.get_modelmeta().custom_metadata_map
    if "pins.min_side" not in meta:
        raise ValueError(f"{path}: not an ONNX file of python -m pins_mms export (no pins.min_side)")
    min_side = int(meta["pins.min_side"])
    _, _, h, w = image1.shape
    a, (top, _, left, _) = pad_to_network(image1.astype(np.float32), min_side)
    b, _ = pad_to_network(image2.astype(np.float32), min_side)
    (flow,) = session.run(["flow"], {"image1": a, "image2": b})
    return flow[:, :, top:top + h, left:left + w]
