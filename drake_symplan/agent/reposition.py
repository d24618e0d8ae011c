"""Putting a box down at its goal spot on the table, which the symbols do not say, setting
aside a box that stands in the arm's way (`clearing_step`), running first the later step
that moves a box a step would be set down against (`unblocking`), and else moving the
step's target to where the step has room (`room_step`).

The symbols do not say where on the table a box stands, so a plan can reach the
goal's atoms with a stack built 20 cm from where the goal has it. `reposition_step` fills
that gap before each step and after the last: a box that rests on nothing in the goal, is
off its goal position (or carries one that is) and is moved by no later step, is put
down beside another box (the same pick/place action) so that it lands within the
tolerance of its goal, on a free spot of the table; what rests on it rides along (a
stack built in the wrong place moves as one, released relative to its own top if need
be), by a grasp the arm does not refuse (skills/geometry.grasp_refused). Its learned
operators have no symbolic effect to predict; the monitor checks
afterwards that the rest of the plan still applies. (Which offsets a step runs with is
abstraction/offsets.py's choice.)
"""

from __future__ import annotations

import numpy as np

from drake_symplan import relations
from drake_symplan.abstraction.continuous import Boxes
from drake_symplan.abstraction.refiner import moves
from drake_symplan.abstraction.set_down import set_down, set_down_meets
from drake_symplan.actions import release_centre
from drake_symplan.boxes import HALF_EXTENTS
from drake_symplan.skills.geometry import grasp_refused, set_down_unseen
from drake_symplan.symbolic.structs import PlanStep, Reposition, reaches

LAND_TOLERANCE = 0.03  # m: a repositioned box must be predicted this near its goal (5 cm check)
CLEARANCE = 0.01  # m: free table between a repositioned box and every other box
REPOSITIONS_PER_OBJECT = 2  # a solve's repositionings at most, per object


def footprint(obj) -> np.ndarray:
    """A perceived box's half extents along world x and y."""
    return np.abs(obj.R[:2, :]) @ np.asarray(HALF_EXTENTS[obj.type])


def rests_on(scene, name: str) -> list[str]:
    """The boxes `name` rests on in a perceived scene (relations.rests_on)."""
    states = scene.object_states()
    return [o for o in scene.names if o != name and relations.rests_on(states[name], states[o])]


def carried(scene, name: str) -> set[str]:
    """The boxes that rest on `name` in a perceived scene, directly or on one that does
    (relations.riders): they ride along when it is carried (skills/pick_place.py carries
    slowly enough)."""
    return set(relations.riders(name, scene.object_states()))


def reposition_step(rest: list[PlanStep], now, goal, tolerance: float) -> Reposition | None:
    """A step that puts a box resting on nothing in the goal, with what rests on it, within
    `tolerance` of its goal position, beside another box, or None. `now`, `goal`: perceived
    scenes by the same names; `rest`: the plan's remaining steps (their sources are left to
    them)."""
    movers = {s.action.source for s in rest}
    boxes = {o.name: o for o in now.objects}
    wanted = {n: goal.object(n).position for n in boxes}

    def error(n) -> float:
        return float(np.linalg.norm(boxes[n].position - wanted[n]))

    loads = {n: carried(now, n) for n in boxes}
    objects = now.object_states()
    sources = sorted((n for n in boxes if n not in movers and not rests_on(goal, n)
                      and max(error(m) for m in {n} | loads[n] - movers) > tolerance),
                     key=lambda n: -max(error(m) for m in {n} | loads[n]))
    for src in sources:
        load, best = loads[src], None
        for move, land in _landings(src, boxes, objects):
            shift = land - boxes[src].position[:2]
            miss = max(float(np.linalg.norm(boxes[n].position[:2] + shift - wanted[n][:2]))
                       for n in {src} | load - movers)
            if miss > LAND_TOLERANCE or (best is not None and miss >= best[0]):
                continue
            if _free(land, src, boxes, load):
                best = (miss, move)
        if best is not None:
            return best[1]
    return None


def _landings(src: str, boxes: dict, objects: dict):
    """(move, where it sets `src` down, xy) of each move of `src` beside or onto another
    box by a grasp the arm does not refuse (skills/geometry.grasp_refused), in the
    cameras' view (set_down_unseen)."""
    length = footprint(boxes[src])[1]
    for move in moves(list(boxes), {src}, lambda _: length):
        if not grasp_refused(move.action, objects) \
                and not set_down_unseen(move.action, objects):
            yield move, release_centre(boxes[move.action.target].position[:2], move.action)


def _free(land: np.ndarray, src: str, boxes: dict, load=frozenset()) -> bool:
    """Is `src` set down at `land` (xy) CLEARANCE clear of every box but its `load`?"""
    size = footprint(boxes[src])
    return all(np.any(np.abs(land - o.position[:2]) >= size + footprint(o) + CLEARANCE)
               for n, o in boxes.items() if n != src and n not in load)


def clearing_step(obstacles, refused: PlanStep, now, keep: set[str]) -> Reposition | None:
    """A step that sets aside a box the arm would strike running `refused` (`obstacles`,
    what the arm named): the first with nothing on it that is not in `keep` (what the goal
    holds where it stands), put down beside another box on a free spot of the
    table, as far as there is from the refused action's boxes; or None. The symbols do
    not say what stands in the arm's way; a person would move it."""
    boxes = {o.name: o for o in now.objects}
    objects = now.object_states()
    ends = {refused.action.source, refused.action.target} & set(boxes)
    away = [boxes[n].position[:2] for n in ends]
    for name in obstacles:
        if name not in boxes or name in keep or carried(now, name):
            continue
        best = None
        for move, land in _landings(name, boxes, objects):
            if move.action.target in ends or not _free(land, name, boxes):
                continue
            far = min(float(np.linalg.norm(land - p)) for p in away) if away else 0.0
            if best is None or far > best[0]:
                best = (far, move)
        if best is not None:
            return best[1]
    return None


def room_step(step: PlanStep, now) -> Reposition | None:
    """A step that moves `step`'s target, resting on nothing and with nothing on it, to a
    free spot of the table where `step`'s source, set down on it as the step sets it,
    meets no box but its target (set_down.set_down_meets): the one nearest where the
    target stands; or None. The symbols do not say where a tower's base stands; a person
    building on it where a box would come to rest against the next structure moves the
    base first."""
    boxes = {o.name: o for o in now.objects}
    src, tgt = step.action.source, step.action.target
    if src not in boxes or tgt not in boxes or carried(now, tgt) or rests_on(now, tgt):
        return None
    seen, here, best = Boxes.of(now), boxes[tgt].position[:2], None
    for move, land in _landings(tgt, boxes, now.object_states()):
        travel = float(np.linalg.norm(land - here))
        if move.action.target == src or (best is not None and travel >= best[0]) \
                or not _free(land, tgt, boxes):
            continue
        on_table = np.r_[land, boxes[tgt].position[2]]  # it rests on nothing now
        if not set_down_meets(set_down(seen, move.action, on_table), step.action):
            best = (travel, move)
    return None if best is None else best[1]


def unblocking(step: PlanStep, rest: list[PlanStep], state, goal, met: set[str]) -> int | None:
    """The index in `rest` (the steps after `step`) of the first that moves a box of `met`
    (those `step` would set its source down against: set_down.set_down_meets), applies in
    `state`, sets its box on or beside one no step before it moves, and, run before
    `step`, leaves the plan reaching `goal`; or None. The symbols
    do not see where a block's ends reach; the order of steps they leave free is the
    agent's to choose (two towers: the second's block set on its cube came to rest on the
    first's top cube, still on the table beside it, and the planner's next plans failed)."""
    for i, later in enumerate(rest):
        first = [step, *rest[:i]]
        if later.action.source not in met or later.action.target in {
                s.action.source for s in first}:  # set against a box the plan still moves
            continue
        if reaches([later, *first, *rest[i + 1:]], state, goal):
            return i
    return None
