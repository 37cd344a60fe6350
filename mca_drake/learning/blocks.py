"""Learnable building blocks shared by the plant-model candidates and the policy.

The paper (Section V-A): every learnable function is a DNN with two linear layers, 64
neurons (128 for the policy), GELU activations and no bias.
"""

from __future__ import annotations

import torch
from torch import nn


class Mlp(nn.Module):
    """Two bias-free linear layers with a GELU between: (..., in_features) -> (..., out_features).

    Args:
        in_features: input width.
        out_features: output width.
        hidden: neurons of the hidden layer (paper: 64 for plant models, 128 for the policy).
    """

    def __init__(self, in_features: int, out_features: int, hidden: int = 64):
        super().__init__()
        if min(in_features, out_features, hidden) < 1:
            raise ValueError("Mlp widths must be positive")
        self.net = nn.Sequential(
            nn.Linear(in_features, hidden, bias=False),
            nn.GELU(),
            nn.Linear(hidden, out_features, bias=False),
        )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x)


def sin_cos_features(value: torch.Tensor) -> torch.Tensor:
    """The paper's feature map g(v) = [sin v, cos v]: (..., n) -> (..., 2n)."""
    return torch.cat([torch.sin(value), torch.cos(value)], dim=-1)


def pose_top(F: torch.Tensor) -> torch.Tensor:
    """The 12 informative entries of a 4x4 pose (or its derivatives): the top 3x4 block,
    row-major, (..., 4, 4) -> (..., 12)."""
    return F[..., :3, :].flatten(-2)
