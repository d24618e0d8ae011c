"""The hand-made reference symbols (learning/handmade.py) on known scenes: the bits, and
the model that reads them from the features alone."""

import numpy as np
import pytest
import torch

from drake_symplan.actions import EFFECT_DIM
from drake_symplan.features import object_features
from drake_symplan.learning.checkpoint import model_from_checkpoint
from drake_symplan.learning.handmade import LARGE, HandmadeSymbols, reference_bits
from drake_symplan.learning.readout import read_symbols


def test_long_and_on_from_the_features_and_contacts():
    eye = np.eye(3)
    # a on b; the long block c beside b, touching it; a padded slot
    state = np.zeros((1, 4, 9), np.float32)
    state[0, 0] = object_features("cube", np.array([0.6, 0.0, 0.075]), eye)
    state[0, 1] = object_features("cube", np.array([0.6, 0.0, 0.025]), eye)
    state[0, 2] = object_features("long", np.array([0.65, 0.0, 0.025]), eye)
    mask = np.array([[True, True, True, False]])
    contacts = np.zeros((1, 4, 4), bool)
    for i, j in ((0, 1), (1, 2)):
        contacts[0, i, j] = contacts[0, j, i] = True
    unary, unary_unc, rel, rel_unc = reference_bits(state, mask, contacts)
    assert unary[0, :, 0].tolist() == [0, 0, 1, 0]
    assert np.argwhere(rel[0, 0]).tolist() == [[0, 1]]  # only a on b
    assert not unary_unc.any() and not rel_unc.any()


def scene(*boxes):
    """Features [1, 8, 9] and mask [1, 8] of boxes (kind, x, y, z), resting flat, unturned,
    padded to 8 slots."""
    state = np.zeros((1, 8, 9), np.float32)
    for i, (kind, *centre) in enumerate(boxes):
        state[0, i] = object_features(kind, np.array(centre), np.eye(3))
    mask = np.zeros((1, 8), bool)
    mask[0, :len(boxes)] = True
    return state, mask


def known(pairs) -> np.ndarray:
    """[1, 8, 8] contacts of slot pairs, both ways."""
    contacts = np.zeros((1, 8, 8), bool)
    for i, j in pairs:
        contacts[0, i, j] = contacts[0, j, i] = True
    return contacts


SCENES = {  # boxes, the pairs in contact, the pairs (i, j) with i on j
    "tower of three": ([("cube", 0.6, 0.0, 0.025), ("cube", 0.6, 0.0, 0.075),
                        ("cube", 0.6, 0.0, 0.125)], [(0, 1), (1, 2)], [(1, 0), (2, 1)]),
    "side by side": ([("cube", 0.6, 0.0, 0.025), ("cube", 0.65, 0.0, 0.025)], [(0, 1)], []),
    "a long block across two cubes": ([("cube", 0.6, -0.05, 0.025),
                                       ("cube", 0.6, 0.05, 0.025),
                                       ("long", 0.6, 0.0, 0.075)],
                                      [(0, 2), (1, 2)], [(2, 0), (2, 1)]),
    "a cube above another, 2 cm apart": ([("cube", 0.6, 0.0, 0.025),
                                          ("cube", 0.6, 0.0, 0.095)], [], []),
    "a long block beside a cube": ([("long", 0.4, 0.0, 0.025), ("cube", 0.45, 0.0, 0.025)],
                                   [(0, 1)], []),
}


@pytest.mark.parametrize("name", sorted(SCENES))
def test_the_handmade_model_reads_the_reference_bits_from_the_features_alone(name):
    boxes, pairs, on = SCENES[name]
    state, mask = scene(*boxes)
    expected = reference_bits(state, mask, known(pairs))
    got = read_symbols(HandmadeSymbols(), state, mask)
    for a, b in zip(got, expected, strict=True):
        np.testing.assert_array_equal(a, b)
    assert sorted(map(tuple, np.argwhere(got[2][0, 0]).tolist())) == on
    assert got[0][0, :, 0].tolist() == [k == "long" for k, *_ in boxes] + [0] * (8 - len(boxes))
    # One scene alone (no batch, every slot real) reads the same.
    single = read_symbols(HandmadeSymbols(), state[0, :len(boxes)])
    np.testing.assert_array_equal(single[2], got[2][0][:, :len(boxes), :len(boxes)])


def test_the_handmade_model_round_trips_through_its_checkpoint_and_predicts_no_effects():
    model = model_from_checkpoint(HandmadeSymbols().checkpoint())
    assert isinstance(model, HandmadeSymbols) and not list(model.parameters())
    assert (model.state_dim, model.n_unary, model.n_relations) == (9, 1, 1)
    state, mask = scene(*SCENES["tower of three"][0])
    logits = model.relation_logits(torch.from_numpy(state), torch.from_numpy(mask))
    assert logits.abs().min() == LARGE  # certain at any margin
    effects = model(torch.from_numpy(state), torch.zeros(1, 8, 8), torch.from_numpy(mask))
    assert effects.shape == (1, 8, EFFECT_DIM) and not effects.any()
    with pytest.raises(ValueError, match="features"):
        HandmadeSymbols(state_dim=7)
