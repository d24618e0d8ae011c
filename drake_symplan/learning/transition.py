"""Symbols that predict their own next values: the symbolic transition objective.

The paper's objective asks the bits only to predict the effect in metres; two scenes with
equal bits and action may then end in different bits (measured: the most frequent
symbolic effect of an action in a situation follows 67 % of the time), and the operators
learned from them branch. This head reads what the decoder reads (each object's message
from its symbols and action, and its related objects') and predicts the bits of the scene
after the action (the same encoder on the next state): unary bits per object, relation
bits per pair from both objects' messages and their relation bits. Trained jointly with
the effect loss (`transition_weight` > 0, best as a fine-tuning of an effect-only run:
`symplan train --init RUN/best.pt`), its error pushes the encoder to put into the bits
before what decides the bits after. The targets are fixed (`target_bits`) and the weight
small (0.003 against the effect loss in m^2): larger, the bits stop carrying what moves. Only symbols and
the action reach it, so what it learns is a property of the symbols, as the operators'
determinism (evaluation/operators.determinism) measures it.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from drake_symplan.learning.layers import MLP


def target_bits(logits: torch.Tensor) -> torch.Tensor:
    """The next scene's bits as the symbols read them (logit > 0), as fixed targets: a
    gradient through them would let the encoder make the next bits predictable by making
    them say less (measured on tests/synthetic_rule.sticky_rule: half of the changes vanish
    from the symbols and the effect error rises four- to tenfold; docs/symbols.md)."""
    return (logits.detach() > 0).to(logits.dtype)


class TransitionHead(nn.Module):
    """Next unary bits from an object's message h_i; next relation bits r_k(i, j) from
    [h_i; h_j; r(i, j); r(j, i)]."""

    def __init__(self, message_dim: int, n_unary: int, n_relations: int, hidden: int = 128):
        super().__init__()
        self.n_relations = n_relations
        self.unary = MLP(message_dim, [hidden], n_unary) if n_unary else None
        self.relation = (MLP(2 * message_dim + 2 * n_relations, [hidden], n_relations)
                         if n_relations else None)

    def forward(self, h: torch.Tensor, relations: torch.Tensor | None
                ) -> tuple[torch.Tensor | None, torch.Tensor | None]:
        """h [B, N, H], relations [B, K, N, N] bits -> (unary logits [B, N, P] or None,
        relation logits [B, K, N, N] or None)."""
        unary = self.unary(h) if self.unary is not None else None
        if self.relation is None or relations is None:
            return unary, None
        b, n, d = h.shape
        r = relations.permute(0, 2, 3, 1)  # [B, i, j, K]
        pair = torch.cat([h.unsqueeze(2).expand(b, n, n, d), h.unsqueeze(1).expand(b, n, n, d),
                          r, r.transpose(1, 2)], dim=-1)
        return unary, self.relation(pair).permute(0, 3, 1, 2)


def transition_loss(predicted: tuple, target_unary: torch.Tensor | None,
                    target_relations: torch.Tensor | None, mask: torch.Tensor) -> torch.Tensor:
    """Binary cross-entropy of the predicted next bits against the next scene's bits, mean over real objects' unary bits plus mean over real
    pairs' relation bits."""
    unary, relations = predicted
    m = mask.to(torch.float32)
    loss = m.new_zeros(())
    if unary is not None and target_unary is not None:
        bce = F.binary_cross_entropy_with_logits(unary, target_unary, reduction="none")
        loss = loss + (bce.mean(-1) * m).sum() / m.sum().clamp(min=1.0)
    if relations is not None and target_relations is not None:
        pair = (m.unsqueeze(-1) * m.unsqueeze(-2)).unsqueeze(1)  # [B, 1, N, N]
        bce = F.binary_cross_entropy_with_logits(relations, target_relations, reduction="none")
        loss = loss + (bce * pair).sum() / (pair.sum() * relations.shape[1]).clamp(min=1.0)
    return loss
