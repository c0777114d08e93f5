"""The Meta-Motion Sense network (Notes S9–S11) in PyTorch, as pins's src/flow/model/mms.rs:
DSMSCE feature and context encoders, the correlation pyramid, `iters` ConvGRU refinements from
zero flow (or a given start), convex 8× upsampling; and RAFT's input padder for any size."""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from .config import MmsConfig
from .corr import corr_lookup, corr_pyramid
from .encoder import Dsmsce
from .update import UpdateBlock
from .upsample import convex_upsample


class Mms(nn.Module):
    """The network. `forward` takes images in [0, 1] whose sides are multiples of 8 and at least
    `config.min_side`; [`FlowModel`] pads any size."""

    def __init__(self, config: MmsConfig):
        super().__init__()
        config.validate()
        self.config = config
        self.feature_encoder = Dsmsce(config.encoder_dims, config.feature_dim, config.dilations,
                                      config.feature_norm)
        self.context_encoder = Dsmsce(config.encoder_dims, config.hidden_dim + config.context_dim,
                                      config.dilations, config.context_norm)
        self.update = UpdateBlock(config)

    def forward(self, image1: torch.Tensor, image2: torch.Tensor, iters: int | None = None,
                flow_init: torch.Tensor | None = None, all_predictions: bool = False):
        """The flow from `image1` to `image2` after `iters` refinements (the config's when None).

        `image1`, `image2`: `[B, 3, H, W]` in [0, 1]; `flow_init`: `[B, 2, H/8, W/8]` in
        1/8-resolution pixels → `[B, 2, H, W]` in pixels, or the list after every refinement when
        `all_predictions` (for the sequence loss of fine-tuning).
        """
        cfg = self.config
        iters = cfg.iters if iters is None else iters
        if iters < 1:
            raise ValueError(f"iters must be at least 1, got {iters}")
        _check_images(image1, image2, cfg.min_side)
        b = image1.shape[0]
        features = self.feature_encoder(torch.cat([image1, image2], 0) * 2.0 - 1.0)
        f1, f2 = features[:b], features[b:]  # [B, C, H/8, W/8]
        context = self.context_encoder(image1 * 2.0 - 1.0)  # [B, Ch + Cc, H/8, W/8]
        pyramid = corr_pyramid(f1, f2, cfg.corr_levels)
        hidden = torch.tanh(context[:, :cfg.hidden_dim])
        context = torch.relu(context[:, cfg.hidden_dim:])
        _, _, h8, w8 = f1.shape
        coords0 = coordinate_grid(b, h8, w8, f1.device, f1.dtype)  # [B, 2, H/8, W/8] = (x, y)
        coords1 = coords0 if flow_init is None else coords0 + flow_init
        predictions = []
        for i in range(iters):
            # RAFT detaches the lookup position: gradients flow through ΔF only.
            coords1 = coords1.detach()
            window = corr_lookup(pyramid, coords1, cfg.corr_radius)
            hidden, delta = self.update(hidden, context, window, coords1 - coords0)
            coords1 = coords1 + delta
            if all_predictions or i + 1 == iters:
                predictions.append(convex_upsample(coords1 - coords0, self.update.mask(hidden)))
        return predictions if all_predictions else predictions[-1]


class FlowModel(nn.Module):
    """[`Mms`] for images of any size: edge-replicated to multiples of 8 (and the pyramid's
    smallest side), centred, and the flow cropped back: pins's `InputPadder`. The iteration count
    is fixed, so the module exports to ONNX as it is.

    `image1`, `image2`: `[B, 3, H, W]` in [0, 1] → `[B, 2, H, W]` in pixels.
    """

    def __init__(self, mms: Mms, iters: int | None = None):
        super().__init__()
        self.mms = mms
        self.iters = mms.config.iters if iters is None else iters

    def forward(self, image1: torch.Tensor, image2: torch.Tensor) -> torch.Tensor:
        h, w = image1.shape[-2:]
        (top, bottom), (left, right) = pads(h, self.mms.config.min_side), pads(w, self.mms.config.min_side)
        pad = (left, right, top, bottom)
        a = F.pad(image1, pad, mode="replicate")
        b = F.pad(image2, pad, mode="replicate")
        flow = self.mms(a, b, self.iters)
        return flow[:, :, top:top + h, left:left + w]


def pads(n, min_side: int):
    """Padding of one side of length n before and after: to a multiple of 8 at least `min_side`,
    split evenly, the odd pixel after."""
    target = (torch.sym_max(n, min_side) + 7) // 8 * 8
    total = target - n
    return total // 2, total - total // 2


def coordinate_grid(b: int, h: int, w: int, device, dtype) -> torch.Tensor:
    """Pixel coordinates `(x, y)` of every cell: `[B, 2, H, W]`."""
    ys, xs = torch.meshgrid(torch.arange(h, device=device, dtype=dtype),
                            torch.arange(w, device=device, dtype=dtype), indexing="ij")
    return torch.stack([xs, ys]).unsqueeze(0).expand(b, 2, h, w)


def _check_images(image1: torch.Tensor, image2: torch.Tensor, min_side: int) -> None:
    if image1.dim() != 4 or image1.shape[1] != 3:
        raise ValueError(f"images must be [B, 3, H, W], got {list(image1.shape)}")
    if image1.shape != image2.shape:
        raise ValueError(f"second image is {list(image2.shape)}, first {list(image1.shape)}")
    if torch.compiler.is_compiling():
        return
    h, w = image1.shape[-2:]
    if h % 8 or w % 8 or min(h, w) < min_side:
        raise ValueError(f"{w}x{h}: sides must be multiples of 8 and at least {min_side} "
                         "(FlowModel pads any size)")
