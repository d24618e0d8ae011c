"""Reference symbols made by hand from the perceived features, not learned: `long(o)` and
`on(o, o')` (in contact, and its centre higher by more than ON_DZ).

No learner is asked to find these; they are the yardstick of what symbols of this kind (a
type bit, a support relation, the contact degrees) can make deterministic on a data set:
`tools/bench_symbol_sets.py --reference` measures them beside a run's learned ones.
"""

from __future__ import annotations

import numpy as np

from drake_symplan.features import FEATURE_NAMES

ON_DZ = 0.03  # m: a box in contact with another and this much higher rests on it
_Z, _LONG = FEATURE_NAMES.index("z"), FEATURE_NAMES.index("is_long")


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
