"""The boxes' geometry, in one place for every layer: object types, sizes, yaw symmetry,
which boxes touch (the contact graph perception reports and the continuous model
predicts), and the goal check (`goal_reached`). A long block's long axis is its local y. No Drake and no torch here.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

SIDE = 0.05  # m: a cube's edge, and a long block's width and height
LONG = 0.25  # m: a long block's length

# Box half-extents (x, y, z) in metres, per object type.
HALF_EXTENTS: dict[str, tuple[float, float, float]] = {
    "cube": (SIDE / 2, SIDE / 2, SIDE / 2),
    "long": (SIDE / 2, LONG / 2, SIDE / 2),
}
OBJECT_TYPES = tuple(HALF_EXTENTS)
# kg, per object type: the catalogue's boxes (models/objects), for where a load's weight is
MASS: dict[str, float] = {"cube": 0.1, "long": 0.4}

# The smallest yaw turn that maps a box onto itself: 90 deg for a cube, 180 for a block.
YAW_PERIOD: dict[str, float] = {"cube": np.pi / 2, "long": np.pi}


def fold_yaw(yaw: float, period: float) -> float:
    """`yaw` folded into [-period / 2, period / 2), e.g. with `YAW_PERIOD[kind]`."""
    return float((yaw + period / 2) % period - period / 2)


GOAL_TOLERANCE = 0.05  # m: a goal is reached when every box is this near its goal position


def goal_distances(where: Mapping[str, np.ndarray], goal: Mapping[str, np.ndarray],
                   spread: Mapping[str, float] | None = None) -> dict[str, float]:
    """Per goal box, its distance (m) from `where` (positions by name) to its goal
    position, plus its `spread` (how unsure a predicted position is) where given."""
    spread = spread or {}
    return {n: float(np.linalg.norm(where[n] - goal[n]) + spread.get(n, 0.0)) for n in goal}


def goal_reached(distances: Mapping[str, float | None],
                 tolerance: float = GOAL_TOLERANCE) -> bool:
    """The goal check, the one place it is written: is every box within `tolerance` of
    its goal? `distances` (m) by name (goal_distances), None for a box not seen; no
    boxes, no goal reached. The agent's check on the perceived scene, the monitor's at a
    plan's end, and bilevel planning's in prediction (with a margin) all ask it."""
    return bool(distances) and all(d is not None and d <= tolerance
                                   for d in distances.values())

CONTACT_TOLERANCE = 0.006  # m; perceived boxes are a few mm off, sampled objects >= 2 cm apart
# Relevance by vicinity (the paper's alternative to contact): surfaces within this are
# neighbours, so a cube released beside another (a 2.5 cm gap, actions.OFFSET_METRES) and
# a row's neighbours are related; the next-but-one box of a tower (5 cm) is not.
VICINITY = 0.035  # m


def _unit_surface(n: int = 7) -> np.ndarray:
    """Points on the surface of the cube [-1, 1]^3: an n x n grid on each face."""
    g = np.linspace(-1.0, 1.0, n)
    uu, vv = np.meshgrid(g, g)
    faces = []
    for axis in range(3):
        a, b = [i for i in range(3) if i != axis]
        for sign in (-1.0, 1.0):
            local = np.zeros((uu.size, 3))
            local[:, axis] = sign
            local[:, a], local[:, b] = uu.ravel(), vv.ravel()
            faces.append(local)
    return np.vstack(faces)


_UNIT_SURFACE = _unit_surface()  # made once: the planner's search asks for many contacts


def box_distance(c1, R1, h1, c2, R2, h2) -> float:
    """Approximate surface distance between two boxes (0 when they overlap): the nearest
    of each box's surface samples to the other box."""
    best = np.inf
    for (ca, Ra, ha), (cb, Rb, hb) in (((c1, R1, h1), (c2, R2, h2)),
                                         ((c2, R2, h2), (c1, R1, h1))):
        local = ((_UNIT_SURFACE * ha) @ np.asarray(Ra).T + (ca - cb)) @ Rb
        outside = np.maximum(np.abs(local) - hb, 0.0)
        best = min(best, float(np.sqrt((outside ** 2).sum(axis=1)).min()))
    return best


def _samples_outside(ca, Ra, ha, cb, Rb, hb) -> np.ndarray:
    """[P]: for P pairs of boxes a, b (arrays [P, 3], [P, 3, 3], [P, 3]), the distance of
    a's surface sample nearest b to b (box_distance's one direction, batched)."""
    a_in_b = Ra.transpose(0, 2, 1) @ Rb  # a's frame to b's, folded into one product
    local = (_UNIT_SURFACE[None] * ha[:, None]) @ a_in_b + (ca - cb)[:, None] @ Rb
    outside = np.maximum(np.abs(local) - hb[:, None], 0.0)
    return np.sqrt((outside ** 2).sum(axis=2)).min(axis=1)


def contact_graph(boxes: dict, tolerance: float = CONTACT_TOLERANCE) -> set[tuple[str, str]]:
    """`boxes`: name -> (center, R, half_extents). Returns sorted name pairs in contact
    (box_distance within `tolerance`, every pair at once)."""
    names = sorted(boxes)
    if len(names) < 2:
        return set()
    c, R, h = (np.array([np.asarray(boxes[n][k], float) for n in names]) for k in range(3))
    i, j = np.triu_indices(len(names), 1)
    reach = np.linalg.norm(h, axis=1)  # nothing of a box is farther from its centre
    near = np.linalg.norm(c[i] - c[j], axis=1) <= reach[i] + reach[j] + tolerance
    i, j = i[near], j[near]
    gaps = np.minimum(_samples_outside(c[i], R[i], h[i], c[j], R[j], h[j]),
                      _samples_outside(c[j], R[j], h[j], c[i], R[i], h[i]))
    return {(names[a], names[b]) for a, b, gap in zip(i, j, gaps, strict=True)
            if gap <= tolerance}


def neighbour_pairs(scene, radius: float) -> set[tuple[str, str]]:
    """The relevance graph of a perceived scene (names, objects with position, R, type;
    contacts): its contact pairs, and with `radius` above CONTACT_TOLERANCE every pair whose
    surfaces are within `radius` (sorted names)."""
    pairs = {tuple(sorted(p)) for p in scene.contacts}
    if radius <= CONTACT_TOLERANCE:
        return pairs
    return pairs | contact_graph({o.name: (np.asarray(o.position), np.asarray(o.R),
                                           np.asarray(HALF_EXTENTS[o.type]))
                                  for o in scene.objects}, radius)


def tilt_of(R: np.ndarray) -> float:
    """Angle (rad) between a box's local z axis and world z for its rotation matrix R,
    folded for box symmetry: a box lying on any face has tilt 0 (the body axis closest to
    vertical counts)."""
    m = np.abs(np.asarray(R)[2, :])
    return float(np.arccos(np.clip(m.max(), -1.0, 1.0)))
