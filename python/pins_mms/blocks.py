"""Building blocks of the encoders (Note S10): padded convolutions, the normalisation switch and
the residual block, with parameter names equal to pins's (src/flow/model/blocks.rs), so a pins
safetensors file loads by name."""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

# pins's (Burn's) InstanceNorm and GroupNorm epsilon.
NORM_EPS = 1e-5


def conv(cin: int, cout: int, k: int, stride: int = 1, dilation: int = 1) -> nn.Conv2d:
    """A k×k convolution padded so that stride 1 keeps the size (dilation included)."""
    p = dilation * (k - 1) // 2
    return nn.Conv2d(cin, cout, k, stride=stride, padding=p, dilation=dilation)


class Affine(nn.Module):
    """The per-channel scale and shift of a normalisation layer (pins's `gamma`, `beta`)."""

    def __init__(self, channels: int):
        super().__init__()
        self.gamma = nn.Parameter(torch.ones(channels))
        self.beta = nn.Parameter(torch.zeros(channels))


class Norm(nn.Module):
    """Instance (per image and channel), group (8 groups) or no normalisation.

    Instance normalisation is group normalisation with one channel per group: one operation for
    both, which exports to ONNX as one node.
    """

    def __init__(self, kind: str, channels: int):
        super().__init__()
        self.kind = kind
        self.groups = channels if kind == "instance" else min(8, channels)
        if kind in ("instance", "group"):
            self.add_module(kind, Affine(channels))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        # [B, C, H, W] → [B, C, H, W]
        if self.kind == "none":
            return x
        a = getattr(self, self.kind)
        return F.group_norm(x, self.groups, a.gamma, a.beta, NORM_EPS)


class ResidualBlock(nn.Module):
    """`relu(skip(x) + relu(norm2(conv2(relu(norm1(conv1(x)))))))`, a 1×1 projection as the skip
    when the shape changes."""

    def __init__(self, cin: int, cout: int, stride: int, norm: str):
        super().__init__()
        self.conv1 = conv(cin, cout, 3, stride)
        self.norm1 = Norm(norm, cout)
        self.conv2 = conv(cout, cout, 3)
        self.norm2 = Norm(norm, cout)
        project = stride != 1 or cin != cout
        self.skip = conv(cin, cout, 1, stride) if project else None
        self.skip_norm = Norm(norm, cout) if project else None

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        # [B, Cin, H, W] → [B, Cout, H/stride, W/stride]
        y = F.relu(self.norm1(self.conv1(x)))
        y = F.relu(self.norm2(self.conv2(y)))
        if self.skip is not None:
            x = self.skip_norm(self.skip(x))
        return F.relu(x + y)
