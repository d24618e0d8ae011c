"""Whether boxes rest where a prediction puts them: what holds a box up, its footprint
over the tops under it, a box that tips off its supports, a load off its one support.
Geometry on the boxes' features only (continuous.Boxes); no simulator. Which box's bottom
meets which top, what stands on the table and what rides on a box are relations.py's
(meets, on_table, riders: one set of tolerances with the skills and the goal checks; here
on heights read once, Boxes.levels)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from drake_symplan.boxes import HALF_EXTENTS, MASS
from drake_symplan.relations import REST_TOL, TABLE_TOL

if TYPE_CHECKING:
    from drake_symplan.abstraction.continuous import Boxes

HULL_TOL = 0.005  # m: a centre this far outside where a box is held still stands
EDGE_TOL = 0.001  # m: a footprint this near a top's edge rests on it (a block 15 cm off a cube)
COVER_INSET = 0.005  # m: a box over another's top this far inside its edges rests on it
LEVEL = np.cos(np.radians(10))  # cos tilt: a box tilted more leans (on the table too)
LOAD_INSET = 0.0105  # m: a load's centre of mass this far inside its one support's edges stands
NEAR_MARGIN = 0.01  # m: beyond the footprints' reach by this, no footprint grown by EDGE_TOL overlaps


def footprint(kind: str, spacing: float = 0.00625) -> np.ndarray:
    """Points over a box's bottom face (local xy, m), `spacing` apart, its edges included."""
    hx, hy = HALF_EXTENTS[kind][:2]
    u = np.linspace(-hx, hx, int(round(2 * hx / spacing)) + 1)
    v = np.linspace(-hy, hy, int(round(2 * hy / spacing)) + 1)
    return np.array([(a, b) for a in u for b in v])


FOOTPRINTS = {kind: footprint(kind) for kind in HALF_EXTENTS}


# Directions in which a centre is compared with where a box is held: a hull of 32 sides
DIRECTIONS = np.stack([np.cos(np.arange(32) * np.pi / 16), np.sin(np.arange(32) * np.pi / 16)],
                      axis=1)


def tips(boxes: Boxes, name: str) -> bool:
    """Does box `name`, as predicted, rest partly on boxes under it with its centre beyond
    where they hold it (outside the convex hull of its footprint's points over their tops,
    by more than HULL_TOL): a block released at its end over one cube, which topples? A box
    on the table, one held across two supports (a bridge) or centred over one, and one held
    up by nothing predicted (its height a regression's mean) are not judged, nor one that
    leans (tilted beyond LEVEL: held by the table or a side too)."""
    i = boxes.names.index(name)
    if boxes.features[i][3] < LEVEL:
        return False
    centre = boxes.features[i][:2].astype(float)
    under = under_of(boxes, i)
    if any(over_top(centre[None], top)[0] for _, *top in under):
        return False  # centred over a support
    points = footprint_points(boxes, i)
    held = np.zeros(len(points), bool)
    for _, *top in under:
        held |= over_top(points, top, -EDGE_TOL)
    if not held.any():
        return False
    reach = (points[held] @ DIRECTIONS.T).max(axis=0)
    return bool(np.any(centre @ DIRECTIONS.T > reach + HULL_TOL))


def overloaded(boxes: Boxes, name: str) -> bool:
    """Does box `name`, level and resting on one box alone, hold a load with a block in it
    (itself and what rides on it, by the catalogue's masses) with the load's centre of mass
    less than LOAD_INSET inside that box's top face? The contacts give a little, and a
    heavy load near an edge leans on them and falls where rigid boxes would stand: a block
    centred 1.8 cm off a cube, and one centred on it with a cube at its end (the load 1.5
    cm off), fell; a block 1.6 cm off stood, and so did towers of cubes 3 mm apart. Loads
    1.0-1.25 cm off stand in five of the thirty eight-box goals, and one 1.1 cm off (a
    cube at the end of two blocks on a cube) fell in a solve: statics cannot tell those
    apart, and the rule leaves them."""
    i = boxes.names.index(name)
    under = supports_of(boxes, i)
    return len(under) == 1 and _overloaded(boxes, i, under[0])


def _overloaded(boxes: Boxes, i: int, support) -> bool:
    """overloaded, box i's one support given (as under_of gives it)."""
    if boxes.features[i][3] < LEVEL:
        return False
    load = [i] + [boxes.names.index(n) for n in boxes.riding(boxes.names[i])]
    kinds = [boxes.shapes[k][0] for k in load]
    if "long" not in kinds:
        return False
    mass = np.array([MASS[k] for k in kinds])
    centre = mass @ boxes.positions[load, :2] / mass.sum()
    return not over_top(centre[None], support[1:], LOAD_INSET)[0]


def on_overhang(boxes: Boxes, name: str) -> bool:
    """Does box `name` rest on a level block held up by one box alone, its centre beyond
    that box's top: on the block's free end? Set down there, its weight comes onto the
    end of a lever: a cube let down on the end of a block balanced on a cube, atop a
    tower, brought the tower down (traced, eight boxes), its load 1.25 cm off centre,
    which stands where it is built without the blow (overloaded)."""
    i = boxes.names.index(name)
    centre = boxes.positions[i, :2][None].astype(float)
    for j, *_ in supports_of(boxes, i):
        if boxes.shapes[j][0] != "long" or boxes.features[j][3] < LEVEL:
            continue
        under = supports_of(boxes, j)
        if len(under) == 1 and not over_top(centre, under[0][1:])[0]:
            return True
    return False


def unstable(boxes: Boxes, names) -> bool:
    """Does one of `names` topple (tips), rest on a block's free end (on_overhang), or it
    or a box it rests on, down to the table, hold its load off its one support
    (overloaded)? Only a raised block loads a box."""
    bottoms, _ = boxes.levels
    raised = any(kind == "long" and bottom > TABLE_TOL
                 for (kind, _, _), bottom in zip(boxes.shapes, bottoms, strict=True))
    for name in names:
        if tips(boxes, name) or raised and on_overhang(boxes, name):
            return True
        i, seen = boxes.names.index(name), set()
        while raised and i not in seen:
            seen.add(i)
            under = supports_of(boxes, i)
            if len(under) != 1:
                break
            if _overloaded(boxes, i, under[0]):
                return True
            i = under[0][0]
    return False


def under_of(boxes: Boxes, i: int) -> list[tuple[int, np.ndarray, np.ndarray, np.ndarray]]:
    """The boxes whose top box i's bottom meets (relations.meets), i off the table
    (relations.on_table), and near enough across that a footprint could overlap a top:
    (index, centre xy, yaw's 2x2 rotation, top's half extents) each. On the heights
    Boxes.levels reads once: the search asks this of every box it moves."""
    bottoms, tops = boxes.levels
    if bottoms[i] <= TABLE_TOL:
        return []
    reach = boxes.reach
    apart = np.linalg.norm(boxes.positions[:, :2] - boxes.positions[i, :2], axis=1)
    near = (np.abs(bottoms[i] - tops) <= REST_TOL) & (apart <= reach + reach[i] + NEAR_MARGIN)
    out = []
    for j in np.flatnonzero(near):
        if j != i:
            kind, centre, R = boxes.shapes[j]
            out.append((int(j), centre[:2], R[:2, :2], np.asarray(HALF_EXTENTS[kind][:2])))
    return out


def supports_of(boxes: Boxes, i: int) -> list[tuple[int, np.ndarray, np.ndarray, np.ndarray]]:
    """The boxes under box i (under_of) that its footprint is over, in part."""
    points = footprint_points(boxes, i)
    return [u for u in under_of(boxes, i) if over_top(points, u[1:]).any()]


def over_top(points: np.ndarray, top, inset: float = 0.0) -> np.ndarray:
    """Which xy `points` [m, 2] lie over a top face `top` (centre xy, yaw's 2x2 rotation,
    half extents: as under_of gives), at least `inset` inside its edges."""
    centre, R, half = top
    return np.all(np.abs((points - centre) @ R) <= half - inset, axis=1)


def footprint_points(boxes: Boxes, i: int) -> np.ndarray:
    """Points over box i's bottom face, world xy."""
    kind, centre, R = boxes.shapes[i]
    return centre[:2] + FOOTPRINTS[kind] @ R[:2, :2].T


def over_tops(points: np.ndarray, centres: np.ndarray, turns: np.ndarray,
              tops: np.ndarray) -> np.ndarray:
    """[s]: is any of the xy `points` [m, 2] over each of s top faces (centres [s, 2],
    yaws' 2x2 rotations [s, 2, 2], half extents [s, 2])?"""
    local = (points[None] - centres[:, None]) @ turns
    return np.all(np.abs(local) <= tops[:, None], axis=2).any(axis=1)
