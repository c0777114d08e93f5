"""Convex 8× upsampling (Note S9), as pins's src/flow/ops/upsample.rs: every full-resolution
flow vector is a softmax-weighted convex combination of 8× the flow at the 3×3 coarse
neighbours of its cell; mask channel `k·64 + s` weighs neighbour k of sub-pixel s = 8i + j."""

from __future__ import annotations

import torch
import torch.nn.functional as F


def convex_upsample(flow: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """`flow` `[B, 2, H, W]` (1/8-resolution pixels), `mask` `[B, 576, H, W]` → `[B, 2, 8H, 8W]`
    (full-resolution pixels)."""
    b, _, h, w = flow.shape
    weights = torch.softmax(mask.reshape(b, 1, 9, 64, h * w), dim=2)
    neighbours = F.unfold(8.0 * flow, 3, padding=1).reshape(b, 2, 9, 1, h * w)  # zero outside
    up = (weights * neighbours).sum(2)  # [B, 2, 64, H·W]
    return up.reshape(b, 2, 8, 8, h, w).permute(0, 1, 4, 2, 5, 3).reshape(b, 2, 8 * h, 8 * w)
