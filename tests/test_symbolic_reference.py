"""The hand-made reference symbols (symbolic/reference.py) on a known scene."""

import numpy as np

from drake_symplan.features import object_features
from drake_symplan.symbolic.reference import reference_bits


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
