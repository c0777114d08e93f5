"""The Dual-Stage Multi-Scale Composite Encoder (DSMSCE, Note S10): a convolutional stem and
residual stages down to 1/8 resolution, then pyramid pooling (Eq. S13) and dilated atrous
spatial pyramid pooling (DASPP, Eqs. S14–S15), as pins's src/flow/model/encoder.rs."""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from .blocks import Norm, ResidualBlock, conv


class PyramidPooling(nn.Module):
    """Eq. S13: P0 = X, P_m = Upsample(AvgPool(X; m×m)) for m = 1, 2, 3, concatenated to 4C
    channels and fused back to C by a 3×3 convolution."""

    def __init__(self, channels: int, norm: str):
        super().__init__()
        self.fuse = conv(4 * channels, channels, 3)
        self.norm = Norm(norm, channels)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        # [B, C, H, W] → [B, C, H, W]
        h, w = x.shape[-2:]
        branches = [x]
        for m in (1, 2, 3):
            # Both as matrix products built from the map's size (pins's resize is the same
            # product): F.adaptive_avg_pool2d and F.interpolate give the same values, but their
            # ONNX export fixes the pooling windows to the size seen at export.
            pooled = pool_matrix(h, m, x).matmul(x).matmul(pool_matrix(w, m, x).T)  # [B, C, m, m]
            up = resize_matrix(m, h, x).matmul(pooled).matmul(resize_matrix(m, w, x).T)
            branches.append(up)  # [B, C, H, W]
        return F.relu(self.norm(self.fuse(torch.cat(branches, 1))))  # [B, 4C, H, W] → [B, C, H, W]


def pool_matrix(n, m: int, like: torch.Tensor) -> torch.Tensor:
    """`[m, n]`: adaptive average pooling of n samples to m, cell i the mean of samples
    floor(i·n/m) ≤ y < ceil((i + 1)·n/m), as F.adaptive_avg_pool2d and pins take them."""
    i = torch.arange(m, device=like.device).reshape(m, 1)
    y = torch.arange(n, device=like.device).reshape(1, -1)
    start = i * n // m
    end = ((i + 1) * n + m - 1) // m
    inside = ((y >= start) & (y < end)).to(like.dtype)
    return inside / (end - start).to(like.dtype)


def resize_matrix(n: int, out, like: torch.Tensor) -> torch.Tensor:
    """`[out, n]`: 1-D linear interpolation from n samples to `out` with align_corners = false:
    output i reads source position (i + ½)·n/out − ½, clamped at 0, between its two neighbours
    (the last sample repeats past the end), as pins's `resize_weights`."""
    i = torch.arange(out, device=like.device, dtype=like.dtype).reshape(-1, 1)
    src = ((i + 0.5) * (n / out) - 0.5).clamp(min=0.0)
    i0 = src.floor().clamp(max=n - 1)
    i1 = (i0 + 1).clamp(max=n - 1)
    t = src - i0
    j = torch.arange(n, device=like.device, dtype=like.dtype).reshape(1, n)
    return (1 - t) * (j == i0).to(like.dtype) + t * (j == i1).to(like.dtype)


class Daspp(nn.Module):
    """Eqs. S14–S15: a 1×1 convolution, 3×3 atrous convolutions at each dilation rate and a
    global-average branch with a 1×1 convolution, concatenated and fused by a 1×1 convolution."""

    def __init__(self, cin: int, cout: int, dilations: tuple[int, ...], norm: str):
        super().__init__()
        self.point = conv(cin, cin, 1)
        self.atrous = nn.ModuleList(conv(cin, cin, 3, 1, d) for d in dilations)
        # pins names this branch `global`, a Python keyword that torch.fx cannot trace:
        # weights.py maps `daspp.global.*` to `daspp.global_.*`.
        self.global_ = conv(cin, cin, 1)
        self.fuse = conv(cin * (len(dilations) + 2), cout, 1)
        self.norm = Norm(norm, cout)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        # [B, C, H, W] → [B, Cout, H, W]
        branches = [F.relu(self.point(x))]
        branches += [F.relu(a(x)) for a in self.atrous]
        g = F.relu(self.global_(x.mean(dim=(2, 3), keepdim=True)))  # [B, C, 1, 1]
        branches.append(g.expand_as(x))
        return self.norm(self.fuse(torch.cat(branches, 1)))


class Dsmsce(nn.Module):
    """One encoder: image `[B, 3, H, W]` (in [−1, 1]) → features `[B, out, H/8, W/8]`."""

    def __init__(self, dims: tuple[int, int, int], out: int, dilations: tuple[int, ...], norm: str):
        super().__init__()
        d1, d2, d3 = dims
        self.stem = conv(3, d1, 7, 2)
        self.stem_norm = Norm(norm, d1)
        self.stage1 = nn.ModuleList([ResidualBlock(d1, d1, 1, norm), ResidualBlock(d1, d1, 1, norm)])
        self.stage2 = nn.ModuleList([ResidualBlock(d1, d2, 2, norm), ResidualBlock(d2, d2, 1, norm)])
        self.stage3 = nn.ModuleList([ResidualBlock(d2, d3, 2, norm), ResidualBlock(d3, d3, 1, norm)])
        self.pyramid = PyramidPooling(d3, norm)
        self.daspp = Daspp(d3, out, dilations, norm)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        # [B, 3, H, W] (H, W multiples of 8) → [B, out, H/8, W/8]
        x = F.relu(self.stem_norm(self.stem(x)))  # [B, d1, H/2, W/2]
        for block in [*self.stage1, *self.stage2, *self.stage3]:
            x = block(x)  # → [B, d3, H/8, W/8]
        return self.daspp(self.pyramid(x))
