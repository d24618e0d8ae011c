"""Building blocks: MLP and the norm-3 linear layer used in front of Gumbel-sigmoids.

Following the paper (after Salimans & Kingma 2016), a layer feeding a Gumbel-sigmoid
scales both its input vector and each weight row to norm `NORM` = 3, so its logits lie
in [-9, 9] plus a bias: large enough to saturate the sigmoid, small enough that its
gradient never vanishes.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
import torch.nn.functional as F
from torch import nn

NORM = 3.0


class MLP(nn.Sequential):
    """Linear+ReLU for each width in `hidden`, then a linear layer to `out_dim`.

    With `out_dim=None` the MLP ends after the last hidden ReLU (a feature extractor).
    """

    def __init__(self, in_dim: int, hidden: Sequence[int], out_dim: int | None = None):
        layers: list[nn.Module] = []
        width = in_dim
        for h in hidden:
            layers += [nn.Linear(width, h), nn.ReLU()]
            width = h
        if out_dim is not None:
            layers.append(nn.Linear(width, out_dim))
            width = out_dim
        super().__init__(*layers)
        self.out_dim = width


def scale_to_norm(x: torch.Tensor, norm: float = NORM, dim: int = -1) -> torch.Tensor:
    """`x` rescaled along `dim` to have Euclidean norm `norm` (zero stays zero)."""
    return norm * F.normalize(x, dim=dim, eps=1e-8)


class NormedLinear(nn.Module):
    """y = (3 x / |x|) . (3 w_k / |w_k|) + b_k for every output k."""

    def __init__(self, in_dim: int, out_dim: int, norm: float = NORM, bias: bool = True):
        super().__init__()
        self.norm = norm
        self.weight = nn.Parameter(torch.empty(out_dim, in_dim))
        nn.init.normal_(self.weight)
        self.bias = nn.Parameter(torch.zeros(out_dim)) if bias else None

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        w = scale_to_norm(self.weight, self.norm, dim=1)
        return F.linear(scale_to_norm(x, self.norm), w, self.bias)

    def extra_repr(self) -> str:
        out_dim, in_dim = self.weight.shape
        return f"in_dim={in_dim}, out_dim={out_dim}, norm={self.norm}"
