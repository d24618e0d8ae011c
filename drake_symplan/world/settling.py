"""Runs a station's physics until its boxes are at rest: after a release (both robots).

At rest: over one SETTLE_CHECK no box on the table moved more than REST_MOVE or turned more
than REST_TURN. Poses, not velocities: a box resting on a flat face keeps a sub-millimetre
discrete-time vibration whose velocity never drops below a threshold, but that perception
can't see and that goes nowhere.
"""

from __future__ import annotations

import numpy as np
from pydrake.math import RigidTransform

SETTLE_CHECK = 0.05  # s between rest checks
REST_MOVE = 5e-4  # m per SETTLE_CHECK: a box that moved less than this is at rest
REST_TURN = np.radians(0.5)  # and turned less than this
OFF_TABLE_Z = -0.02  # m: a box whose centre is below the table top has fallen off it


def settle_until_rest(station, min_seconds: float, max_seconds: float) -> float:
    """Runs `station`'s physics for `min_seconds`, then until its boxes are at rest or
    `max_seconds` have passed; returns the simulated seconds."""
    t0 = station.time()
    if min_seconds > 0.0:
        station.advance_to(t0 + min_seconds)
    poses = list(station.object_poses().values())
    while station.time() - t0 < max_seconds - 1e-9:
        station.advance_to(station.time() + SETTLE_CHECK)
        now = list(station.object_poses().values())
        if all(_at_rest(a, b) for a, b in zip(poses, now, strict=True)):
            break
        poses = now
    return station.time() - t0


def _at_rest(before: RigidTransform, after: RigidTransform) -> bool:
    if after.translation()[2] < OFF_TABLE_Z:
        return True  # fell off the table: it only falls on, and the episode ends
    turn = before.rotation().InvertAndCompose(after.rotation()).ToAngleAxis().angle()
    return bool(np.linalg.norm(after.translation() - before.translation()) < REST_MOVE
                and turn < REST_TURN)
