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
it so that it comes down on the table (`OFFSET_METRES["right"]` from it). The goal's author
executes them in the simulator (evaluation/problems.build_goal); the planner never sees them.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np

from drake_symplan.actions import OFFSET_METRES, Action
from drake_symplan.boxes import HALF_EXTENTS
from drake_symplan.datasets import ObjectState

ARITY = {"on": (2, 2), "tower": (2, None), "bridge": (3, 3), "row": (2, None)}
BRIDGE_SPAN = (0.06, 0.17)  # m: supports' distance along y that the long block spans
ALIGN = 0.02  # m: supports (and row members) within this of each other across y
LEVEL = 0.01  # m: an object this near the table's height stands on the table


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


def check(structures: list[Structure], objects: dict[str, ObjectState]) -> None:
    """SpecError, naming why, unless the start scene `objects` (beliefs) can give them, each
    structure on what the ones before it designed."""
    from drake_symplan.skills.carry import riders  # Drake: not when the CLI is built

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
    state = dict(objects)
    for s in structures:
        for name in s.objects:
            load = [r for r in riders(name, state) if r not in named]
            if load:
                raise SpecError(f"{s.text()!r}: {', '.join(load)} rests on {name} and is not "
                                "named (objects not named stay where they are)")
        _CHECKS[s.word](s, state)
        state = designed(s, state)


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
    out = dict(objects)

    def put(name, on, dy=0.0):
        below = out[on]
        xyz = np.array([*below.position[:2], _top(below) + HALF_EXTENTS[out[name].type][2]])
        out[name] = dc.replace(out[name], position=xyz + [0.0, dy, 0.0], yaw=below.yaw, tilt=0.0)

    names = s.objects
    if s.word in ("on", "tower"):
        for i in reversed(range(len(names) - 1)):
            put(names[i], names[i + 1])
    elif s.word == "bridge":
        put(names[0], names[1], OFFSET_METRES[_bridge_side(s, objects)])
    else:
        for first, second in zip(names, names[1:], strict=False):
            xyz = out[first].position + [0.0, OFFSET_METRES["right"], 0.0]
            xyz[2] = HALF_EXTENTS[out[second].type][2]
            out[second] = dc.replace(out[second], position=xyz, yaw=out[first].yaw, tilt=0.0)
    return out


def _check_row(s: Structure, objects) -> None:
    longs = [n for n in s.objects[:-1] if objects[n].type == "long"]
    if longs:
        raise SpecError(f"{s.text()!r}: {', '.join(longs)} is a long block; a box released "
                        "beside it lands on it, so a row is built along cubes")


# No height check for towers: a scene holds at most 8 boxes (world/scenes.py), 40 cm, and
# the arm built one of 6 (the cameras keep up to 50 cm).
_CHECKS = {"on": lambda s, objects: None, "tower": lambda s, objects: None,
           "bridge": _check_bridge, "row": _check_row}


def build_actions(structures: list[Structure], objects: dict[str, ObjectState]) -> list[Action]:
    """The pick/place actions that build the structures from `objects`, in spec order."""
    actions = []
    for s in structures:
        names = s.objects
        if s.word in ("on", "tower"):  # bottom-up, centred
            actions += [Action(names[i], "center", names[i + 1], "center")
                        for i in reversed(range(len(names) - 1))]
        elif s.word == "bridge":  # off-centre on A, towards B
            actions.append(Action(names[0], "center", names[1], _bridge_side(s, objects)))
        else:  # a row: each released beside the one before, coming down on the table
            actions += [Action(names[i + 1], "center", names[i], "right")
                        for i in range(len(names) - 1)]
        objects = designed(s, objects)
    return actions


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
    need = k + 2 if task == "towers" else k + 1
    if len(names) < need:
        return "too_few_objects"
    names = names[:need]
    if task == "towers":
        cut = int(rng.integers(2, need - 1))  # each tower of two or more
        return [Structure("tower", tuple(names[:cut])), Structure("tower", tuple(names[cut:]))]
    return [Structure(task, tuple(names))]


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
