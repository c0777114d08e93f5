"""The iterative update block (Note S9, Fig. S9a), as pins's src/flow/model/{update,gru}.rs: a
motion encoder of the flow and its correlation features, the ConvGRU of Eqs. S9–S12, the flow
head that predicts ΔF and the mask head of convex upsampling."""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from .blocks import conv
from .config import MmsConfig


class MotionEncoder(nn.Module):
    """(correlation, flow) → motion features, the flow itself kept as the last two channels."""

    def __init__(self, cfg: MmsConfig):
        super().__init__()
        dc, df, dout = cfg.motion_dims
        self.corr1 = conv(cfg.corr_channels, dc, 1)
        self.corr2 = conv(dc, dc, 3)
        self.flow1 = conv(2, df, 7)
        self.flow2 = conv(df, df // 2, 3)
        self.out = conv(dc + df // 2, dout - 2, 3)

    def forward(self, corr: torch.Tensor, flow: torch.Tensor) -> torch.Tensor:
        # corr [B, L·k², H, W], flow [B, 2, H, W] → [B, motion_dims[2], H, W]
        c = F.relu(self.corr2(F.relu(self.corr1(corr))))
        f = F.relu(self.flow2(F.relu(self.flow1(flow))))
        m = F.relu(self.out(torch.cat([c, f], 1)))
        return torch.cat([m, flow], 1)


class ConvGru(nn.Module):
    """Eqs. S9–S12: z = σ(Conv_z([h, x])), r = σ(Conv_r([h, x])),
    h̃ = tanh(Conv_q([r ⊙ h, x])), h' = (1 − z) ⊙ h + z ⊙ h̃."""

    def __init__(self, hidden: int, inp: int):
        super().__init__()
        self.convz = conv(hidden + inp, hidden, 3)
        self.convr = conv(hidden + inp, hidden, 3)
        self.convq = conv(hidden + inp, hidden, 3)

    def forward(self, h: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
        # h [B, Ch, H, W], x [B, Cx, H, W] → [B, Ch, H, W]
        hx = torch.cat([h, x], 1)
        z = torch.sigmoid(self.convz(hx))  # Eq. S9
        r = torch.sigmoid(self.convr(hx))  # Eq. S10
        q = torch.tanh(self.convq(torch.cat([r * h, x], 1)))  # Eq. S11
        return (1 - z) * h + z * q  # Eq. S12


class UpdateBlock(nn.Module):
    """Motion encoder → GRU → flow head (ΔF) and mask head."""

    def __init__(self, cfg: MmsConfig):
        super().__init__()
        self.motion = MotionEncoder(cfg)
        self.gru = ConvGru(cfg.hidden_dim, cfg.motion_dims[2] + cfg.context_dim)
        self.flow1 = conv(cfg.hidden_dim, cfg.head_dim, 3)
        self.flow2 = conv(cfg.head_dim, 2, 3)
        self.mask1 = conv(cfg.hidden_dim, cfg.head_dim, 3)
        self.mask2 = conv(cfg.head_dim, 64 * 9, 1)

    def forward(self, hidden, context, corr, flow):
        # → hidden [B, Ch, H, W], ΔF [B, 2, H, W]
        motion = self.motion(corr, flow)
        hidden = self.gru(hidden, torch.cat([context, motion], 1))
        delta = self.flow2(F.relu(self.flow1(hidden)))
        return hidden, delta

    def mask(self, hidden: torch.Tensor) -> torch.Tensor:
        # [B, Ch, H, W] → [B, 576, H, W]; RAFT scales the logits by 1/4 to balance the gradients.
        return self.mask2(F.relu(self.mask1(hidden))) * 0.25
