"""Building blocks: MLP, the norm-3 linear layer used in front of Gumbel-sigmoids, and
per-object computation on the real objects of a padded batch only (`Packed`).

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


class Packed:
    """The real objects of a padded batch [B, N, ...] as one [M, ...] tensor, and back.

    Padded slots are inert in every model, so per-object layers need not compute them:
    on 2-4-object data a batch padded to 4 slots holds ~40 % padding. Unpacking puts
    zeros in the padded slots; gradients flow through both directions.
    """

    def __init__(self, mask: torch.Tensor):
        self.shape = tuple(mask.shape)
        self.mask = mask
        self.index = mask.reshape(-1).nonzero().squeeze(1)

    def pack(self, x: torch.Tensor) -> torch.Tensor:
        return x.reshape(-1, *x.shape[2:]).index_select(0, self.index)

    def unpack(self, y: torch.Tensor) -> torch.Tensor:
        flat = y.new_zeros(self.shape[0] * self.shape[1], *y.shape[1:])
        return flat.index_copy(0, self.index, y).view(*self.shape, *y.shape[1:])


def packed_transformer(encoder: nn.TransformerEncoder, x: torch.Tensor, packed: Packed):
    """`encoder` (post-norm layers, no dropout) on packed objects x [M, d]; returns [M, d].

    The same function as `encoder(unpacked x, src_key_padding_mask=~mask)` on the real
    objects, with every linear layer applied to real objects only; only the attention
    itself runs on the padded layout.
    """
    b, n = packed.shape
    # A transition without real objects would leave a softmax row with no key (NaN);
    # let its (discarded) rows attend to the padding instead.
    keys = packed.mask | ~packed.mask.any(dim=1, keepdim=True)
    keys = keys[:, None, None, :]
    for layer in encoder.layers:
        if layer.norm_first:
            raise ValueError("packed_transformer implements post-norm layers only")
        attn = layer.self_attn
        heads = attn.num_heads
        qkv = packed.unpack(F.linear(x, attn.in_proj_weight, attn.in_proj_bias))
        q, k, v = qkv.view(b, n, 3, heads, -1).permute(2, 0, 3, 1, 4)  # [B, H, N, d/H] each
        a = F.scaled_dot_product_attention(q, k, v, attn_mask=keys)
        a = packed.pack(a.transpose(1, 2).reshape(b, n, -1))
        x = layer.norm1(x + attn.out_proj(a))
        x = layer.norm2(x + layer.linear2(layer.activation(layer.linear1(x))))
    if encoder.norm is not None:
        x = encoder.norm(x)
    return x
