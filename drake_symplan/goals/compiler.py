"""Goals written in one line (relations.py: on, tower, bridge, row), compiled into the
pick/place actions that build an example of them from a start scene.

Several structures together make one goal, built in the order given, each on what the
ones before it designed (a row of two cubes, a tower on each, a bridge across their tops).
The actions are the robot's own (pick/place on another object, offsets along world y), so
a structure is built the way the robot could: a tower bottom-up with centred places; a
bridge by placing L off-centre on A so that it spans B, B first brought beside A on the
table (or A beside B) where they do not stand 6-17 cm apart along y; a row by releasing
each cube beside the one before it so that it comes down on the table, from whichever of
its boxes leaves the row room on the table. A box resting on one about to be moved or built
on is first set down on the table beside a free-standing box (`_park`). The goal's author
executes the actions in the simulator (goals/problems.build_goal); the planner never sees
them: it gets the relations, and the example's symbols for the pairs they name.
"""

from __future__ import annotations

import dataclasses as dc
from collections import Counter

import numpy as np

from drake_symplan.actions import OFFSET_METRES, Action, along_y, release_shift
from drake_symplan.boxes import HALF_EXTENTS
from drake_symplan.datasets import ObjectState
from drake_symplan.relations import (
    ALIGN,
    Relation,
    SpecError,
    listed,
    on_table,
    riders,
    top,
)
from drake_symplan.world.scenes import WORKSPACE_X, WORKSPACE_Y, ObjectSpec, footprints_overlap

BRIDGE_SPAN = (0.06, 0.17)  # m: supports' distance along y that the long block spans
LEVEL = 0.01  # m: supports' tops this near each other are level
PARK_GAP = 0.015  # m: a box set down on the table keeps this clear of every other footprint
# m: the highest tower top a goal may ask for: the cameras see up to 50 cm and the arm's
# carry clears the tallest box by 10 cm under its lift limit
MAX_TOP = 0.40


def moved(s: Relation) -> tuple[str, ...]:
    """The objects that the structure's own actions pick up (a bridge's support brought
    beside the other aside)."""
    if s.word in ("on", "tower"):
        return s.objects[:-1]
    return s.objects[:1] if s.word == "bridge" else s.objects[1:]


def check(structures: list[Relation], objects: dict[str, ObjectState]) -> list[Action]:
    """The actions that build the structures from the start scene `objects` (beliefs),
    each on what the ones before it designed (`build_actions`); SpecError, naming why,
    where no start or this start cannot give them."""
    check_names(structures, objects)
    return build_actions(with_supports(structures, objects), objects)


def with_supports(structures: list[Relation], objects: dict[str, ObjectState]) -> list[Relation]:
    """The structures, with a row of two towers' bottoms put first where a bridge spans
    the towers' tops and the bottoms stand apart: what brings the supports together."""
    tops = {t.objects[0]: t.objects[-1] for t in structures if t.word in ("on", "tower")}
    rows = {frozenset(r.objects) for r in structures if r.word == "row"}
    first = []
    for s in structures:
        _, a, b = s.objects if s.word == "bridge" else (None, None, None)
        if a in tops and b in tops:
            bottoms = (tops[a], tops[b])
            cubes = all(objects[n].type == "cube" for n in bottoms)
            if cubes and frozenset(bottoms) not in rows and not _bridge_fits(
                    objects[bottoms[0]], objects[bottoms[1]]):
                first.append(Relation("row", bottoms))
    return first + list(structures)


def check_names(structures: list[Relation], objects: dict[str, ObjectState]) -> None:
    """SpecError for names the start lacks, a box two structures move, a bridge without a
    long block, a row along long blocks or a tower above MAX_TOP."""
    named = [n for s in structures for n in s.objects]
    unknown = sorted(set(named) - set(objects))
    if unknown:
        raise SpecError(f"{listed(unknown)} not in the start scene (it holds "
                        f"{listed(sorted(objects), 16)})")
    movers = Counter(n for s in structures for n in moved(s))
    twice = sorted(n for n, times in movers.items() if times > 1)
    if twice:
        raise SpecError(f"{', '.join(twice)} named twice")
    for s in structures:
        kinds = [objects[n].type for n in s.objects]
        if s.word == "bridge" and kinds[0] != "long":
            raise SpecError(f"{s.text()!r}: {s.objects[0]} is a {kinds[0]}; a bridge needs a "
                            "long block")
        if s.word == "row" and "long" in kinds[:-1]:
            longs = [n for n, k in zip(s.objects[:-1], kinds, strict=False) if k == "long"]
            raise SpecError(f"{s.text()!r}: {', '.join(longs)} is a long block; a box released "
                            "beside it lands on it, so a row is built along cubes")
        height = sum(2 * HALF_EXTENTS[k][2] for k in kinds)
        if s.word == "tower" and height > MAX_TOP:
            raise SpecError(f"{s.text()!r}: {100 * height:.0f} cm tall; the arm stacks up to "
                            f"{100 * MAX_TOP:.0f} cm")


def designed(s: Relation, objects: dict[str, ObjectState]) -> dict[str, ObjectState]:
    """`objects` once the structure is built as designed: a placed box centred (or, a
    bridge's span, offset) on its support, turned as it, a row's cubes on the table."""
    for action, beside in _structure_actions(s, objects):
        objects = _placed(objects, action, beside)
    return objects


def _placed(objects: dict[str, ObjectState], action: Action, beside: bool = False):
    """`objects` once `action` is done as designed: the source released over the target by
    its release shift, turned as the target, on its top or (`beside`) on the table."""
    below, src = objects[action.target], objects[action.source]
    xyz = below.position + along_y(release_shift(action))
    xyz[2] = (0.0 if beside else top(below)) + HALF_EXTENTS[src.type][2]
    return {**objects, action.source: dc.replace(src, position=xyz, yaw=below.yaw, tilt=0.0)}


def _free(spot: ObjectSpec, objects: dict[str, ObjectState], skip: set[str]) -> bool:
    """Is `spot` on the table's workspace and clear (PARK_GAP) of every box not in `skip`?"""
    half = HALF_EXTENTS[spot.type]
    x, y = spot.position[:2]
    inside = (WORKSPACE_X[0] + half[1] <= x <= WORKSPACE_X[1] - half[1]
              and WORKSPACE_Y[0] + half[1] <= y <= WORKSPACE_Y[1] - half[1])
    return inside and not any(
        footprints_overlap(spot, ObjectSpec(o.name, o.type, list(o.position), o.yaw), -PARK_GAP)
        for n, o in objects.items() if n not in skip)


def _beside(mover: ObjectState, anchor: ObjectState, side: str) -> ObjectSpec:
    """Where `mover` lands released beside `anchor` on `side`, on the table."""
    xy = anchor.position[:2] + along_y(OFFSET_METRES[side], 2)
    return ObjectSpec(mover.name, mover.type, [*xy, HALF_EXTENTS[mover.type][2]], anchor.yaw)


def _bridge_fits(a: ObjectState, b: ObjectState) -> bool:
    d = np.abs(b.position[:2] - a.position[:2])
    return d[0] <= ALIGN and BRIDGE_SPAN[0] <= d[1] <= BRIDGE_SPAN[1]


def _bridge_actions(s: Relation, objects: dict[str, ObjectState]) -> list[tuple[Action, bool]]:
    """A bridge's actions: its supports brought together first where they stand apart."""
    span, a, b = s.objects
    if _bridge_fits(objects[a], objects[b]):
        if abs(top(objects[a]) - top(objects[b])) > LEVEL:
            raise SpecError(f"{s.text()!r}: the supports' tops are not level ({a} at "
                            f"{100 * top(objects[a]):.0f} cm, {b} at "
                            f"{100 * top(objects[b]):.0f} cm)")
        side = "right" if objects[b].position[1] > objects[a].position[1] else "left"
        return [(Action(span, "center", a, side), False)]
    for mover, anchor in ((b, a), (a, b)):
        if not on_table(objects[anchor]) or objects[mover].type != "cube":
            continue
        for side in ("right", "left"):
            if _free(_beside(objects[mover], objects[anchor], side), objects, {mover, span}):
                return [(Action(mover, "center", anchor, side), True),
                        (Action(span, "center", anchor, side), False)]
    raise SpecError(f"{s.text()!r}: {a} and {b} stand apart and neither can be set beside the "
                    f"other on the table ({span} spans supports {100 * BRIDGE_SPAN[0]:.0f}-"
                    f"{100 * BRIDGE_SPAN[1]:.0f} cm apart along y)")


def _row_fits(s: Relation, objects: dict[str, ObjectState], i: int, at: np.ndarray,
              yaw: float) -> bool:
    """Would the row stand clear with its i-th box at `at` (xy), turned by `yaw`?"""
    step = OFFSET_METRES["right"]
    spots = [ObjectSpec(n, objects[n].type, [*(at + along_y((j - i) * step, 2)),
                                             HALF_EXTENTS[objects[n].type][2]], yaw)
             for j, n in enumerate(s.objects)]
    return all(_free(spot, objects, set(s.objects)) for spot in spots)


def _row_from(names: tuple[str, ...], i: int) -> list[tuple[Action, bool]]:
    """A row's actions built out from its i-th box, each released beside its neighbour."""
    after = [(Action(names[j], "center", names[j - 1], "right"), True)
             for j in range(i + 1, len(names))]
    before = [(Action(names[j], "center", names[j + 1], "left"), True)
              for j in reversed(range(i))]
    return after + before


def _row_actions(s: Relation, objects: dict[str, ObjectState]) -> list[tuple[Action, bool]]:
    """A row's actions, built out from the first of its boxes that stands on the table with
    room for the whole row along y; failing that, its first box is set down first beside
    a box on the table where the row has room."""
    names = s.objects
    for i, n in enumerate(names):
        if on_table(objects[n]) and _row_fits(s, objects, i, objects[n].position[:2],
                                              objects[n].yaw):
            return _row_from(names, i)
    first = objects[names[0]]
    for anchor in sorted((o for n, o in objects.items() if n not in names and on_table(o)),
                         key=lambda o: float(np.linalg.norm(o.position[:2]
                                                            - first.position[:2]))):
        for side in ("right", "left"):
            spot = _beside(first, anchor, side)
            if _row_fits(s, objects, 0, np.asarray(spot.position[:2]), anchor.yaw) \
                    and _free(spot, objects, set(names)):
                return [(Action(names[0], "center", anchor.name, side), True),
                        *_row_from(names, 0)]
    raise SpecError(f"{s.text()!r}: the table has no room for {len(names)} boxes "
                    f"{100 * OFFSET_METRES['right']:.1f} cm apart along y")


def _structure_actions(s: Relation, objects: dict[str, ObjectState]) -> list[tuple[Action, bool]]:
    """The actions that build `s` alone from `objects`, each with whether its source comes
    down on the table beside its target (else on it)."""
    names = s.objects
    if s.word in ("on", "tower"):  # bottom-up, centred
        return [(Action(names[i], "center", names[i + 1], "center"), False)
                for i in reversed(range(len(names) - 1))]
    if s.word == "bridge":
        return _bridge_actions(s, objects)
    return _row_actions(s, objects)


def build_actions(structures: list[Relation], objects: dict[str, ObjectState]) -> list[Action]:
    """The pick/place actions that build the structures from `objects`, in spec order, each
    box resting on a source (or a target built on) set down on the table first (`_park`);
    SpecError if a structure cannot stand on what the ones before designed, or a box in
    the way belongs to what is built or has nowhere to go."""
    planned, movers = objects, []  # the structures designed as if nothing were in the way
    for s in structures:
        for action, beside in _structure_actions(s, planned):
            movers.append(action.source)
            planned = _placed(planned, action, beside)
    reserved = [planned[n] for n in dict.fromkeys(movers)]  # kept free
    actions, built = [], set()
    for s in structures:
        for action, beside in _structure_actions(s, objects):
            carried = riders(action.source, objects)
            below = riders(action.target, objects) if not beside else []
            loads = [*carried, *(r for r in below if r != action.source and r not in carried)]
            for name in reversed(loads):  # the top of a stack first
                if name in built:
                    raise SpecError(f"{s.text()!r}: {name} rests on {action.source} or "
                                    f"{action.target}, which is built on before it; name the "
                                    "structures in another order")
                park = _park(name, objects, reserved)
                actions.append(park)
                objects = _placed(objects, park, beside=True)
            actions.append(action)
            objects = _placed(objects, action, beside)
            built |= {action.source, action.target}
        built |= set(s.objects)
    return actions


def _park(name: str, objects: dict[str, ObjectState], reserved: list[ObjectState]) -> Action:
    """The action that sets `name` down on the table beside the nearest box standing there
    with room beside it (released 7.5 cm along y from it, turned as it), clear of every box
    and of the `reserved` places the structures will take."""
    box = objects[name]
    bottoms = sorted((o for n, o in objects.items() if n != name and on_table(o)),
                     key=lambda o: float(np.linalg.norm(o.position[:2] - box.position[:2])))
    others = {**{f"reserved {o.name}": o for o in reserved}, **objects}
    for anchor in bottoms:
        for side in ("right", "left"):
            if _free(_beside(box, anchor, side), others, {name, f"reserved {name}"}):
                return Action(name, "center", anchor.name, side)
    raise SpecError(f"{name} is in the way and no box on the table has room beside it to "
                    "set it down")
