"""Goals written in one line, compiled into the pick/place actions that build them.

    on A B             A on B
    tower A B ... Z    each on the next, Z where it stands
    bridge L A B       the long block L across the supports A and B
    row A B ... Z      each 7.5 cm along +y from the one before, on the table

Several structures together make one goal, built in the order given, each on what the
ones before it designed (a row of two cubes, a tower on each, a bridge across their tops);
an object is moved by one structure at most, and objects not named stay where they are.
The actions are the robot's own (pick/place on another object, offsets along world y), so
a structure is built the way the robot could: a tower bottom-up with centred places, a
bridge by placing L off-centre on A so that it spans B (A and B must stand 6-17 cm apart
along y with their tops level by then), a row by releasing each cube beside the one before
it so that it comes down on the table (`OFFSET_METRES["right"]` from it). A named box
resting on one about to be moved or built on is first set down on the table beside a
free-standing box (`_park`), so a start with stacks takes more actions than boxes placed.
The goal's author executes them in the simulator (evaluation/problems.build_goal); the
planner never sees them.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np

from drake_symplan.actions import OFFSET_METRES, Action, along_y, release_shift
from drake_symplan.boxes import HALF_EXTENTS
from drake_symplan.datasets import ObjectState
from drake_symplan.world.scenes import WORKSPACE_X, WORKSPACE_Y, ObjectSpec, footprints_overlap

ARITY = {"on": (2, 2), "tower": (2, None), "bridge": (3, 3), "row": (2, None)}
BRIDGE_SPAN = (0.06, 0.17)  # m: supports' distance along y that the long block spans
ALIGN = 0.02  # m: supports (and row members) within this of each other across y
LEVEL = 0.01  # m: an object this near the table's height stands on the table
PARK_GAP = 0.015  # m: a box set down on the table keeps this clear of every other footprint


class SpecError(ValueError):
    """A spec the world cannot satisfy, with why (one line)."""


@dc.dataclass(frozen=True)
class Structure:
    word: str
    objects: tuple[str, ...]

    def text(self) -> str:
        return " ".join((self.word, *self.objects))


def parse(specs: list[str]) -> list[Structure]:
    """Structures of one-line specs ('tower o3 o1 o0', ...); SpecError on a bad word or count."""
    out = []
    for spec in specs:
        words = spec.split()
        if not words:
            raise SpecError("an empty spec")
        word, names = words[0], tuple(words[1:])
        if word not in ARITY:
            raise SpecError(f"{spec!r}: unknown word {word!r}; expected one of {sorted(ARITY)}")
        low, high = ARITY[word]
        if len(names) < low or (high is not None and len(names) > high):
            count = f"{low}" if low == high else f"at least {low}"
            raise SpecError(f"{spec!r}: {word} takes {count} objects, got {len(names)}")
        out.append(Structure(word, names))
    return out


def moved(s: Structure) -> tuple[str, ...]:
    """The objects that the structure's actions pick up."""
    if s.word in ("on", "tower"):
        return s.objects[:-1]
    return s.objects[:1] if s.word == "bridge" else s.objects[1:]


def check(structures: list[Structure], objects: dict[str, ObjectState]) -> list[Action]:
    """The actions that build the structures from the start scene `objects` (beliefs),
    each on what the ones before it designed (`build_actions`); SpecError, naming why,
    where the start cannot give them."""
    named = [n for s in structures for n in s.objects]
    unknown = sorted(set(named) - set(objects))
    if unknown:
        raise SpecError(f"{', '.join(unknown)} not in the start scene (it holds "
                        f"{', '.join(sorted(objects))})")
    movers = [n for s in structures for n in moved(s)]
    twice = sorted({n for s in structures for n in s.objects if s.objects.count(n) > 1}
                   | {n for n in movers if movers.count(n) > 1})
    if twice:
        raise SpecError(f"{', '.join(twice)} named twice")
    return build_actions(structures, objects)


def _top(o: ObjectState) -> float:
    return float(o.position[2] + HALF_EXTENTS[o.type][2])


def _check_bridge(s: Structure, objects) -> None:
    span, a, b = (objects[n] for n in s.objects)
    if span.type != "long":
        raise SpecError(f"{s.text()!r}: {span.name} is a {span.type}; a bridge needs a long block")
    if abs(_top(a) - _top(b)) > LEVEL:
        raise SpecError(f"{s.text()!r}: the supports' tops are not level ({a.name} at "
                        f"{100 * _top(a):.0f} cm, {b.name} at {100 * _top(b):.0f} cm)")
    d = np.abs(b.position[:2] - a.position[:2])
    if d[0] > ALIGN or not BRIDGE_SPAN[0] <= d[1] <= BRIDGE_SPAN[1]:
        raise SpecError(f"{s.text()!r}: {a.name} and {b.name} stand {100 * d[1]:.0f} cm apart "
                        f"along y and {100 * d[0]:.0f} cm across; {span.name} spans supports "
                        f"{100 * BRIDGE_SPAN[0]:.0f}-{100 * BRIDGE_SPAN[1]:.0f} cm apart along y, "
                        f"within {100 * ALIGN:.0f} cm across")


def _bridge_side(s: Structure, objects) -> str:
    """The release offset that puts the span on its first support, towards the second."""
    _, a, b = s.objects
    return "right" if objects[b].position[1] > objects[a].position[1] else "left"


def designed(s: Structure, objects: dict[str, ObjectState]) -> dict[str, ObjectState]:
    """`objects` once the structure is built as designed: a placed box centred (or, a
    bridge's span, offset) on its support, turned as it, a row's cubes on the table."""
    for action in _structure_actions(s, objects):
        objects = _placed(objects, action, beside=s.word == "row")
    return objects


def _placed(objects: dict[str, ObjectState], action: Action, beside: bool = False):
    """`objects` once `action` is done as designed: the source released over the target by
    its release shift, turned as the target, on its top or (`beside`) on the table."""
    below, src = objects[action.target], objects[action.source]
    xyz = below.position + along_y(release_shift(action))
    xyz[2] = (0.0 if beside else _top(below)) + HALF_EXTENTS[src.type][2]
    return {**objects, action.source: dc.replace(src, position=xyz, yaw=below.yaw, tilt=0.0)}


def _check_row(s: Structure, objects) -> None:
    longs = [n for n in s.objects[:-1] if objects[n].type == "long"]
    if longs:
        raise SpecError(f"{s.text()!r}: {', '.join(longs)} is a long block; a box released "
                        "beside it lands on it, so a row is built along cubes")


# No height check for towers: a scene holds at most 8 boxes (world/scenes.py), 40 cm, and
# the arm built one of 6 (the cameras keep up to 50 cm).
_CHECKS = {"on": lambda s, objects: None, "tower": lambda s, objects: None,
           "bridge": _check_bridge, "row": _check_row}


def _structure_actions(s: Structure, objects: dict[str, ObjectState]) -> list[Action]:
    """The actions that build `s` alone from `objects`."""
    names = s.objects
    if s.word in ("on", "tower"):  # bottom-up, centred
        return [Action(names[i], "center", names[i + 1], "center")
                for i in reversed(range(len(names) - 1))]
    if s.word == "bridge":  # off-centre on A, towards B
        return [Action(names[0], "center", names[1], _bridge_side(s, objects))]
    # a row: each released beside the one before, coming down on the table
    return [Action(names[i + 1], "center", names[i], "right") for i in range(len(names) - 1)]


def build_actions(structures: list[Structure], objects: dict[str, ObjectState]) -> list[Action]:
    """The pick/place actions that build the structures from `objects`, in spec order, each
    box resting on a source (or a target built on) set down on the table first (`_park`);
    SpecError if a structure cannot stand on what the ones before designed, an unnamed box
    rests on a named one, or a box in the way belongs to what is built or has nowhere to go."""
    from drake_symplan.skills.carry import riders  # Drake: not when the CLI is built

    named = {n for s in structures for n in s.objects}
    planned = objects  # the structures designed as if nothing were in the way: kept free
    for s in structures:
        planned = designed(s, planned)
    reserved = [planned[n] for s in structures for n in moved(s)]
    actions, built = [], set()
    for s in structures:
        for name in s.objects:
            load = [r for r in riders(name, objects) if r not in named]
            if load:
                raise SpecError(f"{s.text()!r}: {', '.join(load)} rests on {name} and is not "
                                "named (objects not named stay where they are)")
        _CHECKS[s.word](s, objects)
        for action in _structure_actions(s, objects):
            carried = riders(action.source, objects)
            below = riders(action.target, objects) if s.word != "row" else []
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
            objects = _placed(objects, action, beside=s.word == "row")
            built |= {action.source, action.target}
        built |= set(s.objects)
    return actions


def _park(name: str, objects: dict[str, ObjectState], reserved: list[ObjectState]) -> Action:
    """The action that sets `name` down on the table beside the nearest box standing there
    with room beside it (released 7.5 cm along y from it, turned as it), clear of every box
    and of the `reserved` places the structures will take."""
    box = objects[name]
    bottoms = sorted((o for n, o in objects.items() if n != name and o.position[2] < LEVEL
                      + HALF_EXTENTS[o.type][2]),
                     key=lambda o: float(np.linalg.norm(o.position[:2] - box.position[:2])))
    others = [ObjectSpec(o.name, o.type, list(o.position), o.yaw)
              for o in [*objects.values(), *reserved] if o.name != name]
    half = HALF_EXTENTS[box.type]
    for anchor in bottoms:
        for side in ("right", "left"):
            xy = anchor.position[:2] + along_y(OFFSET_METRES[side], 2)
            spot = ObjectSpec(name, box.type, [*xy, half[2]], anchor.yaw)
            inside = (WORKSPACE_X[0] + half[1] <= xy[0] <= WORKSPACE_X[1] - half[1]
                      and WORKSPACE_Y[0] + half[1] <= xy[1] <= WORKSPACE_Y[1] - half[1])
            if inside and not any(footprints_overlap(spot, o, -PARK_GAP) for o in others):
                return Action(name, "center", anchor.name, side)
    raise SpecError(f"{name} is in the way and no box on the table has room beside it to "
                    "set it down")


TASKS = ("tower", "row", "towers", "bridge", "mixed")  # `problems make --task`


def sample_structures(rng: np.random.Generator, objects: dict[str, ObjectState], task: str,
                      k: int) -> list[Structure] | str:
    """A random goal of `task` that takes `k` actions to build from `objects`: a tower of
    k + 1 boxes, a row of k + 1 cubes, two towers of k + 2 boxes, a bridge (`_bridge`), or
    a tower beside a bridge (mixed, k >= 3); or why the scene cannot give one (a string)."""
    names = [str(n) for n in rng.permutation(sorted(objects))]
    if task in ("bridge", "mixed"):
        if k < (3 if task == "mixed" else 2):
            return "k_too_small"
        k_bridge = k if task == "bridge" else int(rng.integers(2, k))
        bridge = _bridge(names, objects, k_bridge)
        if isinstance(bridge, str) or task == "bridge":
            return bridge
        used = {n for st in bridge for n in st.objects}
        rest = [n for n in names if n not in used]
        if len(rest) < k - k_bridge + 1:
            return "too_few_objects"
        return [Structure("tower", tuple(rest[:k - k_bridge + 1])), *bridge]
    if task == "row":
        names = [n for n in names if objects[n].type == "cube"]
    if task == "towers" and k < 2:
        return "k_too_small"
    need = k + 2 if task == "towers" else k + 1
    if len(names) < need:
        return "too_few_objects"
    names = names[:need]
    if task == "towers":
        cut = int(rng.integers(2, need - 1))  # each tower of two or more
        return [Structure("tower", tuple(names[:cut])), Structure("tower", tuple(names[cut:]))]
    return [Structure(task, tuple(names))]


def sample_goal(rng: np.random.Generator, objects: dict[str, ObjectState], task: str,
                ks: tuple[int, ...], tries: int = 100) -> list[Structure] | str:
    """A random goal of `task` whose build from `objects` takes one of `ks` actions, the
    boxes set down out of the way counted (a start with stacks needs them), or why none was
    found in `tries` samples of each structure size, sizes in random order (a string)."""
    why = "k_unreachable"
    for size in rng.permutation(np.arange(1, max(ks) + 1)):
        for _ in range(tries):
            structures = sample_structures(rng, objects, task, size)
            if isinstance(structures, str):
                why = structures
                break  # the scene cannot give this size
            try:
                actions = check(structures, objects)
            except SpecError:
                why = "spec_refused"
                continue
            if len(actions) in ks:
                return structures
    return why


def _bridge(names: list[str], objects: dict[str, ObjectState], k: int) -> list[Structure] | str:
    """A bridge k >= 2 actions away: a row of two cubes, a tower of k // 2 cubes standing on
    each (the row's two are their bottoms), a long block across their tops, and for an odd
    k a cube on the block."""
    cubes = [n for n in names if objects[n].type == "cube"]
    longs = [n for n in names if objects[n].type == "long"]
    h, extra = k // 2, k % 2
    if len(cubes) < 2 * h + extra or not longs:
        return "too_few_objects"
    left, right = cubes[:h], cubes[h:2 * h]  # each listed top first, its bottom last
    out = [Structure("row", (left[-1], right[-1]))]
    out += [Structure("tower", tuple(t)) for t in (left, right) if len(t) > 1]
    out.append(Structure("bridge", (longs[0], left[0], right[0])))
    if extra:
        out.append(Structure("on", (cubes[2 * h], longs[0])))
    return out


def holds(structure: Structure, positions: dict[str, np.ndarray], types: dict[str, str],
          tolerance: float = 0.02) -> str | None:
    """None if `positions` (box centres) hold the structure, else what is wrong."""
    p = {n: np.asarray(positions[n], float) for n in structure.objects}
    height = {n: 2 * HALF_EXTENTS[types[n]][2] for n in structure.objects}
    names = structure.objects
    if structure.word in ("on", "tower"):
        for top, below in zip(names, names[1:], strict=False):
            dz = p[top][2] - p[below][2] - (height[top] + height[below]) / 2
            if abs(dz) > tolerance or np.linalg.norm(p[top][:2] - p[below][:2]) > tolerance:
                return f"{top} is not on {below}"
        return None
    if structure.word == "bridge":
        span, a, b = names
        for o in (a, b):
            if abs(p[span][2] - p[o][2] - (height[span] + height[o]) / 2) > tolerance:
                return f"{span} does not rest on {o}"
        return None
    step = OFFSET_METRES["right"]
    for first, second in zip(names, names[1:], strict=False):
        d = p[second] - p[first]
        if abs(d[1] - step) > tolerance or abs(d[0]) > tolerance or abs(d[2]) > tolerance:
            return f"{second} is not {100 * step:.1f} cm along y from {first} on the table"
    return None
