"""Naming by position: which object of one view is which object of another, by where it is."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from scipy.optimize import linear_sum_assignment


def match_by_position(a: Mapping[str, np.ndarray], b: Mapping[str, np.ndarray],
                      max_distance: float = np.inf) -> dict[str, str]:
    """Name in `a` -> name in `b` (each maps names to positions), by the one-to-one
    assignment that minimises the summed distance; pairs `max_distance` or farther apart
    are left out, and so are the names of the larger side that find no partner."""
    if not a or not b:
        return {}
    names_a, names_b = list(a), list(b)
    pos_a = np.stack([a[n] for n in names_a])
    pos_b = np.stack([b[n] for n in names_b])
    cost = np.linalg.norm(pos_a[:, None] - pos_b[None], axis=2)
    rows, cols = linear_sum_assignment(cost)
    return {names_a[r]: names_b[c] for r, c in zip(rows, cols, strict=True)
            if cost[r, c] < max_distance}
