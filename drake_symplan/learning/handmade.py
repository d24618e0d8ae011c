"""Reference symbols made by hand from the perceived features, not learned: `long(o)` and
`on(o, o')` (in contact, and its centre higher by more than ON_DZ).

No learner is asked to find these; they are the yardstick of what symbols of this kind (a
type bit, a support relation, the contact degrees) can make deterministic on a data set
(`tools/bench_symbol_sets.py --reference` measures them beside a run's learned ones) and
the ceiling a planner on symbols of this kind reaches: `HandmadeSymbols` reads them as a
model does, so that a bundle of it (`symplan bundle --symbols handmade`) plans with them.
"""

from __future__ import annotations

import numpy as np
import torch

from drake_symplan.actions import EFFECT_DIM
from drake_symplan.boxes import CONTACT_TOLERANCE
from drake_symplan.features import FEATURE_DIM, FEATURE_NAMES, touching
from drake_symplan.learning.models import EffectModel

ON_DZ = 0.03  # m: a box in contact with another and this much higher rests on it
_Z, _LONG = FEATURE_NAMES.index("z"), FEATURE_NAMES.index("is_long")
HANDMADE = "handmade"  # the model name its checkpoints carry (checkpoint.model_from_checkpoint)
LARGE = 100.0  # the magnitude of its logits: every bit certain at any read-out margin below
HANDMADE_RULE = {  # what a bundle of it says its symbols are (provenance.json)
    "p0": "long(o): the feature is_long",
    "r0": "on(o, o'): o touches o' (boxes.contact_graph of the boxes the features give, "
          "each resting on a face) and o's centre is more than on_dz higher",
    "on_dz": ON_DZ, "contact_tolerance": CONTACT_TOLERANCE}


def reference_bits(state: np.ndarray, mask: np.ndarray, contacts: np.ndarray):
    """(unary [T, M, 1], unary_uncertain, relational [T, 1, M, M], relational_uncertain)
    of whole scenes' features `state` [T, M, D], `mask` [T, M], perceived `contacts`
    [T, M, M]: p0 = long, r0(i, j) = i on j; every bit certain."""
    real = mask.astype(bool)
    unary = ((state[..., _LONG] > 0.5) & real)[..., None].astype(np.uint8)
    z = state[..., _Z]
    on = contacts & (z[:, :, None] > z[:, None, :] + ON_DZ) & real[:, :, None] & real[:, None, :]
    relational = on[:, None].astype(np.uint8)
    return unary, np.zeros(unary.shape, bool), relational, np.zeros(relational.shape, bool)


class HandmadeSymbols(EffectModel):
    """`reference_bits` as a symbol model, from the features alone: p0 = long, r0(i, j) =
    i on j, with the contacts of the boxes' geometry as the features give it
    (features.touching: each box resting on a face, as box_of reads it). Its logits are
    +-LARGE, so every bit is certain. No learned parameters (the EffectModel's
    normalisation buffers only, unused).

    It predicts no effects: `forward` gives zeros (nothing moves). A bundle of it plans on
    its symbols (`--planning symbolic`); a mode that rolls the continuous model forward
    needs a trained one beside it (the bundle's continuous.pt, `symplan bundle
    --continuous RUN`)."""

    n_relations = 1

    def __init__(self, state_dim: int = FEATURE_DIM):
        if state_dim != FEATURE_DIM:
            raise ValueError(f"hand-made symbols read the {FEATURE_DIM} features of "
                             f"features.FEATURE_NAMES, not {state_dim}")
        super().__init__(state_dim, 0)
        self.n_unary = 1
        self._config = {"state_dim": state_dim}

    def checkpoint(self) -> dict:
        """What rebuilds it (checkpoint.model_from_checkpoint): a bundle's model.pt."""
        return {"model": HANDMADE, "model_config": self.config(),
                "model_state": self.state_dict()}

    @staticmethod
    def _logits(bits: np.ndarray, like: torch.Tensor) -> torch.Tensor:
        return torch.as_tensor(np.where(bits > 0, LARGE, -LARGE), dtype=like.dtype,
                               device=like.device)

    def unary_logits(self, state: torch.Tensor) -> torch.Tensor:
        """[B, N, 1] logits of long(o)."""
        x = state.detach().cpu().numpy()
        real = np.ones(x.shape[:2], bool)
        return self._logits(reference_bits(x, real, np.zeros(real.shape + real.shape[-1:],
                                                             bool))[0], state)

    def relation_logits(self, state: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """[B, 1, N, N] logits of on(o_i, o_j)."""
        x, real = state.detach().cpu().numpy(), mask.detach().cpu().numpy().astype(bool)
        return self._logits(reference_bits(x, real, touching(x, real))[2], state)

    def forward(self, state: torch.Tensor, action: torch.Tensor, mask: torch.Tensor):
        """Zero effects [B, N, EFFECT_DIM]: no prediction (class docstring)."""
        return state.new_zeros(state.shape[:2] + (EFFECT_DIM,))
