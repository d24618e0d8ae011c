"""Choosing a plan step's offsets so the placed object lands where the goal scene has it.

The learned symbols say that a box ends on another, not where along it: a plan step
`pick o3 at its centre, release on o1's right` and the same step released at o1's centre
can predict the same symbolic effect. The planner picks either; the 5 cm check cannot
accept both. Before a step runs, `refine_step` looks for the domain's operators that are
interchangeable with it here (same arguments, preconditions that hold in the believed
state, and from its predicted successor the rest of the plan still applies and reaches the
goal's atoms) and takes the one whose offsets
put the source nearest its perceived goal position, as an NSRT's sampler picks the
continuous parameters of a step (here: among the three discrete offsets per hand).

Where the source rests on the target in the goal scene, the position that counts is the
one relative to the target (the target may move later); otherwise it is absolute.

The symbols do not say where on the table a box stands either, so a plan can reach the
goal's atoms with a stack built 20 cm from where the goal has it. `reposition_step` fills
that gap before each step and after the last: a box that rests on nothing in the goal, is
off its goal position (or carries one that is) and is moved by no later step, is put
down beside another box (the same pick/place action) so that it lands within the
tolerance of its goal, on a free spot of the table; what rests on it rides along (a
stack built in the wrong place moves as one, released relative to its own top if need
be). Its learned operators have no symbolic effect to predict; the monitor checks
afterwards that the rest of the plan still applies.
"""

from __future__ import annotations

import numpy as np

from drake_symplan.abstraction.bilevel import equivalents, moves
from drake_symplan.actions import release_centre, release_shift
from drake_symplan.boxes import HALF_EXTENTS
from drake_symplan.symbolic.structs import PlanStep, Reposition, Step

MIN_GAIN = 0.01  # m: a change of offsets must bring the source this much nearer its goal
LAND_TOLERANCE = 0.03  # m: a repositioned box must be predicted this near its goal (5 cm check)
CLEARANCE = 0.01  # m: free table between a repositioned box and every other box
RESTS_ON = 0.03  # m: a box in contact with another and this much higher rests on it
REPOSITIONS_PER_OBJECT = 2  # a solve's repositionings at most, per object


def landing_error(step: PlanStep, now: dict[str, np.ndarray], goal: dict[str, np.ndarray],
                  goal_contacts) -> float:
    """How far (m, along world y, the offsets' axis) the step's source would land from its
    goal position, with the source's grasp point released over the target's release point."""
    action = step.action
    shift = release_shift(action)
    src, tgt = action.source, action.target
    if tuple(sorted((src, tgt))) in goal_contacts:
        want = goal[src][1] - goal[tgt][1]
    else:
        want = goal[src][1] - now[tgt][1]
    return abs(shift - want)


def refine_step(operators, step: Step, rest: list[PlanStep], state, goal_atoms,
                now: dict[str, np.ndarray], goal: dict[str, np.ndarray], goal_contacts) -> Step:
    """`step`, or the interchangeable step (see `equivalents`) that lands its source at
    least MIN_GAIN nearer its goal; `now` and `goal` are perceived positions by name."""
    options = equivalents(operators, step, rest, state, goal_atoms)
    if len(options) == 1:
        return step
    contacts = {tuple(sorted(p)) for p in goal_contacts}
    errors = [landing_error(s, now, goal, contacts) for s in options]
    best = int(np.argmin(errors))
    return options[best] if errors[0] - errors[best] >= MIN_GAIN else step


def footprint(obj) -> np.ndarray:
    """A perceived box's half extents along world x and y."""
    return np.abs(obj.R[:2, :]) @ np.asarray(HALF_EXTENTS[obj.type])


def rests_on(scene, name: str) -> list[str]:
    """The boxes `name` rests on in a perceived scene (in contact with them, and higher)."""
    box = scene.object(name)
    return [o for a, b in scene.contacts if name in (a, b)
            for o in [b if a == name else a]
            if box.position[2] - scene.object(o).position[2] > RESTS_ON]


def carried(scene, name: str) -> set[str]:
    """The boxes that rest on `name` in a perceived scene, directly or on one that does:
    they ride along when it is carried (skills/pick_place.py carries slowly enough)."""
    load, todo = set(), [name]
    while todo:
        base = todo.pop()
        for other in scene.names:
            if other != name and other not in load and base in rests_on(scene, other):
                load.add(other)
                todo.append(other)
    return load


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
    sources = sorted((n for n in boxes if n not in movers and not rests_on(goal, n)
                      and max(error(m) for m in {n} | loads[n] - movers) > tolerance),
                     key=lambda n: -max(error(m) for m in {n} | loads[n]))
    for src in sources:
        size, load = footprint(boxes[src]), loads[src]
        best = None
        for move in moves(list(boxes), {src}, lambda _, length=size[1]: length):
            land = release_centre(boxes[move.action.target].position[:2], move.action)
            shift = land - boxes[src].position[:2]
            miss = max(float(np.linalg.norm(boxes[n].position[:2] + shift - wanted[n][:2]))
                       for n in {src} | load - movers)
            if miss > LAND_TOLERANCE or (best is not None and miss >= best[0]):
                continue
            if all(np.any(np.abs(land - o.position[:2]) >= size + footprint(o) + CLEARANCE)
                   for n, o in boxes.items() if n != src and n not in load):
                best = (miss, move)
        if best is not None:
            return best[1]
    return None
