"""All-pairs correlation (Note S9), as pins's src/flow/ops/corr.rs: `C[p, q] = f1(p) · f2(q) / √C`,
average-pooled 2×2 into a pyramid, and looked up in a (2r+1)² window around x + F(x) at every
level (positions scaled by 2^−l) by bilinear interpolation, zero outside the level.

The lookup gathers the (2r+2)² integer patch of every pixel and blends it with the shared
fractional weights, as pins does, rather than RAFT's `grid_sample`: the same taps without the
round trip through normalised coordinates (whose rounding, amplified by 12 updates, doubles
the difference from pins on KITTI) and without RAFT's division by a level's width − 1, zero
on a level one cell wide.
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F

# Positions are clamped this far out before flooring (a diverged flow stays finite and reads
# zeros), as pins's kernel saturates its integer anchors.
FAR = float(1 << 24)


def corr_pyramid(f1: torch.Tensor, f2: torch.Tensor, levels: int) -> list[torch.Tensor]:
    """`f1`, `f2`: `[B, C, H, W]` → levels `[B·H·W, H/2^l, W/2^l]`."""
    b, c, h, w = f1.shape
    corr = torch.matmul(f1.reshape(b, c, h * w).transpose(1, 2), f2.reshape(b, c, h * w))  # [B, HW, HW]
    corr = (corr / math.sqrt(c)).reshape(b * h * w, 1, h, w)
    pyramid = [corr]
    for _ in range(1, levels):
        hl, wl = corr.shape[-2:]
        # A level already one cell wide keeps that side (pins and RAFT alike).
        k = (min(2, hl), min(2, wl))
        corr = F.avg_pool2d(corr, k, stride=k)
        pyramid.append(corr)
    return [level[:, 0] for level in pyramid]


def corr_lookup(pyramid: list[torch.Tensor], coords: torch.Tensor, radius: int) -> torch.Tensor:
    """The window of every level around `coords` (x, y in frame 2 of every cell); level l fills
    channels `[l·(2r+1)², (l+1)·(2r+1)²)`, window row (dy) major.

    `coords`: `[B, 2, H, W]` → `[B, levels·(2r+1)², H, W]`
    """
    b, _, h, w = coords.shape
    c = coords.permute(0, 2, 3, 1).reshape(b * h * w, 2)  # [N, 2] = (x, y)
    k = 2 * radius + 1
    out = []
    for l, level in enumerate(pyramid):
        window = window_lookup(level, c / float(1 << l), radius)  # [N, k, k]
        out.append(window.reshape(b, h, w, k * k))
    return torch.cat(out, 3).permute(0, 3, 1, 2)  # [B, L·k², H, W]


def window_lookup(level: torch.Tensor, c: torch.Tensor, r: int) -> torch.Tensor:
    """Bilinear (2r+1)² window of `level` around each position, zero outside: the (2r+2)²
    integer patch gathered once, blended with the shared fractional weights.

    `level`: `[N, hl, wl]`, `c`: `[N, 2]` → `[N, 2r+1 (dy), 2r+1 (dx)]`
    """
    n, hl, wl = level.shape
    k, kk = 2 * r + 1, 2 * r + 2
    c = c.clamp(-FAR, FAR)
    x, y = c[:, 0:1], c[:, 1:2]  # [N, 1]
    xf, yf = torch.floor(x), torch.floor(y)
    fx = (x - xf).reshape(n, 1, 1)
    fy = (y - yf).reshape(n, 1, 1)
    offs = torch.arange(kk, device=c.device).reshape(1, kk)
    ix = xf.long() - r + offs  # [N, kk]
    iy = yf.long() - r + offs
    vx = ((ix >= 0) & (ix < wl)).to(level.dtype)
    vy = ((iy >= 0) & (iy < hl)).to(level.dtype)
    idx = iy.clamp(0, hl - 1).reshape(n, kk, 1) * wl + ix.clamp(0, wl - 1).reshape(n, 1, kk)
    p = level.reshape(n, hl * wl).gather(1, idx.reshape(n, kk * kk)).reshape(n, kk, kk)
    p = p * (vy.reshape(n, kk, 1) * vx.reshape(n, 1, kk))  # [N, kk, kk], zero outside
    gx, gy = 1.0 - fx, 1.0 - fy
    return (p[:, :k, :k] * (gy * gx) + p[:, :k, 1:] * (gy * fx)
            + p[:, 1:, :k] * (fy * gx) + p[:, 1:, 1:] * (fy * fx))
