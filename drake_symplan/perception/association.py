"""Identity across an action: which object perceived after it is which object before it.

Hypotheses are scored: the grasp held an object (the source, or a neighbour under the
grasp point) that moved from the grasp point to the release point carrying whatever was
stacked on it, or it held nothing (nothing moved). Each predicts where every
before-object should be; an optimal assignment (Hungarian) matches predictions to the
after-objects, a type mismatch costing extra and an object the hypothesis leaves still
costing more for every centimetre it moved beyond a push. The cheaper hypothesis wins.
No simulator state is used.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import linear_sum_assignment

from drake_symplan.actions import Action, grasp_point, release_point
from drake_symplan.boxes import HALF_EXTENTS

TYPE_MISMATCH_COST = 0.3  # m-equivalent
UNMATCHED_COST = 0.5
GRASP_SLACK = 0.01  # m: a grasp point this far outside a footprint may still hold that box
SHARED_MOVES = 1.0  # 1/m: weight of the squared distance (0.0025 m-equivalent at 5 cm)
# A box the hand did not hold moves at most about a push of the fingers; farther, each
# metre costs STRAY_COST more. Without it, a stack put on its own rider (three blocks)
# was read as nothing held and every block moved 10 cm under another's name. A fall is not
# a push: only the sideways move and a rise count (a cube knocked off a tower's top drops
# 10 cm; counted whole, the tower below was read as slid out from under itself, three
# cubes under each other's names, and the plan went on with the names swapped).
PUSH_REACH = 0.06  # m
STRAY_COST = 2.0  # m-equivalent per m beyond PUSH_REACH
# Nor does a box the hand did not hold rise, beyond a lean or a see-saw's tilt: a block set
# on another's end shoved the lower one 12 cm along, and without this that read best as
# the lower block risen onto the upper one's place, the carried one landed 12 cm off.
RISE_SLACK = 0.02  # m
RISE_COST = 10.0  # m-equivalent per m beyond RISE_SLACK


def stacked_on(scene, name: str) -> set[str]:
    """Objects resting (transitively) on `name`, from the perceived contact graph."""
    above, frontier = set(), [name]
    while frontier:
        base = scene.object(frontier.pop())
        for a, b in scene.contacts:
            other = b if a == base.name else a if b == base.name else None
            if other and other not in above and other != name:
                if scene.object(other).position[2] > base.position[2] + 0.03:
                    above.add(other)
                    frontier.append(other)
    return above


def _grasp_candidates(before, action: Action) -> list[str]:
    """Objects the closing fingers could hold: the source, and any object whose footprint
    contains the grasp point (an off-centre grasp can land on a touching neighbour)."""
    src = before.object(action.source)
    point = grasp_point(src.position[:2], action)
    names = [action.source]
    for o in before.objects:
        local = (point - o.position[:2]) @ o.R[:2, :2]
        half = np.array(HALF_EXTENTS[o.type][:2]) + GRASP_SLACK
        if o.name != action.source and np.all(np.abs(local) <= half):
            names.append(o.name)
    return names


def _predictions(before, action: Action, grasped: str | None
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Where each before-object should be if `grasped` was held (None: nothing), and
    whether it was carried."""
    pred = np.stack([o.position for o in before.objects]).astype(float)
    carried = np.zeros(len(pred), bool)
    if grasped is None:
        return pred, carried
    src = before.object(action.source)
    held = before.object(grasped)
    tgt = before.object(action.target)
    # TCP goes from source + grasp offset to target + release offset (skills/pick_place).
    shift = release_point(tgt.position, action) - grasp_point(src.position, action)
    # Lands on the target's top.
    shift[2] = (tgt.position[2] + (HALF_EXTENTS[tgt.type][2] + HALF_EXTENTS[held.type][2])
                - held.position[2])
    moving = {grasped} | stacked_on(before, grasped)
    for i, o in enumerate(before.objects):
        if o.name in moving:
            pred[i] += shift
            carried[i] = True
    return pred, carried


def _assign(before, after, pred: np.ndarray, carried: np.ndarray
            ) -> tuple[float, dict[str, str]]:
    if not after.objects:
        return UNMATCHED_COST * len(before.objects), {}
    obs = np.stack([o.position for o in after.objects])
    moves = obs[None, :, :] - pred[:, None, :]
    dist = np.linalg.norm(moves, axis=2)
    # The squared term breaks ties toward moves shared out: a push that shifts two
    # touching cubes 5 cm each is not one cube left and the other moved 10 cm.
    cost = dist + SHARED_MOVES * dist ** 2
    rise = np.maximum(moves[..., 2], 0.0)
    pushed = np.hypot(np.linalg.norm(moves[..., :2], axis=2), rise)
    cost[~carried] += STRAY_COST * np.maximum(pushed[~carried] - PUSH_REACH, 0.0) \
        + RISE_COST * np.maximum(rise[~carried] - RISE_SLACK, 0.0)
    types_b = np.array([o.type for o in before.objects])
    types_a = np.array([o.type for o in after.objects])
    cost = cost + TYPE_MISMATCH_COST * (types_b[:, None] != types_a[None, :])
    rows, cols = linear_sum_assignment(cost)
    total = cost[rows, cols].sum() + UNMATCHED_COST * abs(len(before.objects)
                                                          - len(after.objects))
    mapping = {before.objects[r].name: after.objects[c].name for r, c in zip(rows, cols,
                                                                           strict=True)}
    return float(total), mapping


def associate(before, after, action: Action) -> dict[str, str]:
    """Maps before-names to after-names (objects lost from view are left out)."""
    best = None
    for grasped in [*_grasp_candidates(before, action), None]:
        total, mapping = _assign(before, after, *_predictions(before, action, grasped))
        if best is None or total < best[0]:
            best = (total, mapping)
    return best[1]
