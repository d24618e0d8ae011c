"""The boxes' geometry, in one place for every layer: object types, sizes and yaw symmetry.

A long block's long axis is its local y. No Drake and no torch here.
"""

from __future__ import annotations

import numpy as np

SIDE = 0.05  # m: a cube's edge, and a long block's width and height
LONG = 0.25  # m: a long block's length

# Box half-extents (x, y, z) in metres, per object type.
HALF_EXTENTS: dict[str, tuple[float, float, float]] = {
    "cube": (SIDE / 2, SIDE / 2, SIDE / 2),
    "long": (SIDE / 2, LONG / 2, SIDE / 2),
}
OBJECT_TYPES = tuple(HALF_EXTENTS)

# The smallest yaw turn that maps a box onto itself: 90 deg for a cube, 180 for a block.
YAW_PERIOD: dict[str, float] = {"cube": np.pi / 2, "long": np.pi}


def fold_yaw(yaw: float, period: float) -> float:
    """`yaw` folded into [-period / 2, period / 2), e.g. with `YAW_PERIOD[kind]`."""
    return float((yaw + period / 2) % period - period / 2)
