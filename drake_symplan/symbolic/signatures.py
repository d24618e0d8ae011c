"""Which learned relation atoms say a goal relation, learned from the data.

A relation a person names (relations.py: on, tower, bridge, row) is about pairs of boxes of
one kind (relations.PAIR_KINDS: on, bears, beside). One perceived example of the structure
reads every relational bit of its pairs, and some of those bits are incidental: a cube
squarely on a cube and one set 1 cm off read different r0 and r1, the same r2. A kind's
*signature* is the bits, each way, that the data's perceived pairs of that kind read alike
in at least SUPPORT of them; a goal of relations asks for those atoms of its pairs
(abstraction.Abstraction.goal_atoms), so any outcome that makes the relation reaches it.

Learned when a bundle is made (`symplan bundle`), from the whole perceived scenes after
each transition: their features give the pairs' kinds by relations.pair_unmet, the model's
read-out their bits. Stored in the bundle's operators.json info ("relation_signatures").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drake_symplan.datasets import ObjectState
from drake_symplan.features import object_state
from drake_symplan.relations import PAIR_KINDS, pair_unmet

SUPPORT = 0.8  # a bit read alike in at least this share of a kind's pairs is its signature
MIN_PAIRS = 20  # a kind seen in fewer pairs of the data has no signature
SAMPLE = 6000  # scenes read at most (a random sample, seeded): the shares settle by then


@dataclass(frozen=True)
class Signature:
    """A pair kind's bits: (relation index, value) from the first box to the second
    (`forward`) and from the second to the first (`backward`), as Relation.pairs orders
    a pair; `pairs`: how many of the data's pairs of this kind they were learned from."""

    kind: str
    pairs: int
    forward: tuple[tuple[int, int], ...]
    backward: tuple[tuple[int, int], ...]

    def atoms(self, first: str, second: str) -> set[tuple[str, str, str]]:
        """The signature's atoms of the pair (first, second), as bit_atoms names them."""
        return ({(f"r{k}" if v else f"not_r{k}", first, second) for k, v in self.forward}
                | {(f"r{k}" if v else f"not_r{k}", second, first) for k, v in self.backward})

    def to_json(self) -> dict:
        return {"pairs": self.pairs, "forward": [list(b) for b in self.forward],
                "backward": [list(b) for b in self.backward]}


def from_json(data: dict | None) -> dict[str, Signature]:
    """The signatures stored in a bundle's info (none for a bundle made before them)."""
    return {kind: Signature(kind, int(s["pairs"]), tuple(tuple(b) for b in s["forward"]),
                            tuple(tuple(b) for b in s["backward"]))
            for kind, s in (data or {}).items()}


def to_json(signatures: dict[str, Signature]) -> dict:
    return {kind: s.to_json() for kind, s in signatures.items()}


def kinds_of(states: dict[int, ObjectState]) -> list[tuple[str, int, int]]:
    """Every (kind, first, second) pair of one scene's boxes that holds its kind."""
    return [(kind, i, j) for i in states for j in states if i != j for kind in PAIR_KINDS
            if pair_unmet(kind, states[i], states[j]) is None]


def learn_signatures(relational: np.ndarray, features: np.ndarray, mask: np.ndarray,
                     support: float = SUPPORT, sample: int = SAMPLE, seed: int = 0
                     ) -> dict[str, Signature]:
    """Each pair kind's signature (module docstring) from whole perceived scenes: bits
    `relational` [T, K, M, M], features [T, M, D], `mask` [T, M] of the real boxes; at
    most `sample` scenes, drawn with `seed`."""
    scenes = np.arange(len(mask))
    if len(scenes) > sample:
        scenes = np.sort(np.random.default_rng(seed).choice(scenes, sample, replace=False))
    n_rel = relational.shape[1]
    ones = {kind: np.zeros((2, n_rel)) for kind in PAIR_KINDS}
    count = dict.fromkeys(PAIR_KINDS, 0)
    for t in scenes:
        states = {int(i): object_state(str(i), features[t, i]) for i in np.flatnonzero(mask[t])}
        for kind, i, j in kinds_of(states):
            count[kind] += 1
            ones[kind] += np.stack([relational[t, :, i, j], relational[t, :, j, i]])
    out = {}
    for kind, n in count.items():
        if n < MIN_PAIRS or not n_rel:
            continue
        share = ones[kind] / n
        way = [tuple((k, int(share[d, k] >= support)) for k in range(n_rel)
                     if share[d, k] >= support or share[d, k] <= 1 - support) for d in (0, 1)]
        out[kind] = Signature(kind, n, way[0], way[1])
    return out
