"""Relation signatures (symbolic/signatures.py): the bits every perceived pair of a kind
reads alike, learned from scenes built to hold the kind."""

from __future__ import annotations

import numpy as np

from drake_symplan.features import object_features
from drake_symplan.symbolic.signatures import (
    MIN_PAIRS,
    Signature,
    from_json,
    learn_signatures,
    to_json,
)


def stacked_scenes(n: int):
    """n scenes of cube 0 squarely on cube 1 and cube 2 apart; r0 from 0 to 1 alternates
    (incidental), r2 from 0 to 1 is always set, nothing from 1 to 0."""
    eye = np.eye(3)
    rows = [object_features("cube", np.array(p), eye)
            for p in ([0.7, 0.0, 0.075], [0.7, 0.0, 0.025], [0.5, 0.3, 0.025])]
    features = np.repeat(np.stack(rows)[None], n, axis=0)
    relational = np.zeros((n, 3, 3, 3), np.uint8)
    relational[:, 2, 0, 1] = 1
    relational[::2, 0, 0, 1] = 1
    return relational, features, np.ones((n, 3), bool)


def test_the_signature_keeps_the_bits_every_pair_of_the_kind_reads_alike():
    signatures = learn_signatures(*stacked_scenes(40))
    on = signatures["on"]
    assert on.pairs == 40
    assert on.forward == ((1, 0), (2, 1))  # r0 alternates: incidental, left out
    assert on.backward == ((0, 0), (1, 0), (2, 0))
    assert on.atoms("a", "b") == {("not_r1", "a", "b"), ("r2", "a", "b"), ("not_r0", "b", "a"),
                                  ("not_r1", "b", "a"), ("not_r2", "b", "a")}
    assert "beside" not in signatures  # no pair of the scenes stands in a row


def test_a_kind_seen_in_too_few_pairs_has_no_signature_and_signatures_round_trip():
    assert learn_signatures(*stacked_scenes(MIN_PAIRS - 1)) == {}
    signatures = learn_signatures(*stacked_scenes(MIN_PAIRS))
    assert from_json(to_json(signatures)) == signatures
    assert from_json(None) == {}
    assert Signature("on", 3, ((2, 1),), ()).atoms("x", "y") == {("r2", "x", "y")}
