"""Goals written in one line, compiled into the pick/place actions that build them.

    on A B             A on B
    tower A B ... Z    each on the next, Z where it stands
    bridge L A B       the long block L across the supports A and B
    row A B ... Z      each 7.5 cm along +y from the one before, on the table

Several structures together make one goal; objects not named stay where they are. The
actions are the robot's own (pick/place on another object, offsets along world y), so a
structure is built the way the robot could: a tower bottom-up with centred places, a bridge
by placing L off-centre on A so that it spans B (A and B must already stand 6-17 cm apart
along y), a row by releasing each cube beside the one before it so that it comes down on
the table (`OFFSET_METRES["right"]` from it). The goal's author executes them in the
simulator (evaluation/problems.build_goal); the planner never sees them.
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


def check(structures: list[Structure], objects: dict[str, ObjectState]) -> None:
    """SpecError, naming why, unless the start scene `objects` (beliefs) can give them."""
    from drake_symplan.skills.carry import riders  # Drake: not when the CLI is built

    named = [n for s in structures for n in s.objects]
    unknown = sorted(set(named) - set(objects))
    if unknown:
        raise SpecError(f"{', '.join(unknown)} not in the start scene (it holds "
                        f"{', '.join(sorted(objects))})")
    twice = sorted({n for n in named if named.count(n) > 1})
    if twice:
        raise SpecError(f"{', '.join(twice)} named twice")
    for s in structures:
        for name in s.objects:
            load = [r for r in riders(name, objects) if r not in named]
            if load:
                raise SpecError(f"{s.text()!r}: {', '.join(load)} rests on {name} and is not "
                                "named (objects not named stay where they are)")
        _CHECKS[s.word](s, objects)


def _check_bridge(s: Structure, objects) -> None:
    span, a, b = (objects[n] for n in s.objects)
    if span.type != "long":
        raise SpecError(f"{s.text()!r}: {span.name} is a {span.type}; a bridge needs a long block")
    for o in (a, b):
        if abs(o.position[2] - HALF_EXTENTS[o.type][2]) > LEVEL:
            raise SpecError(f"{s.text()!r}: the support {o.name} does not stand on the table")
    d = np.abs(b.position[:2] - a.position[:2])
    if d[0] > ALIGN or not BRIDGE_SPAN[0] <= d[1] <= BRIDGE_SPAN[1]:
        raise SpecError(f"{s.text()!r}: {a.name} and {b.name} stand {100 * d[1]:.0f} cm apart "
                        f"along y and {100 * d[0]:.0f} cm across; {span.name} spans supports "
                        f"{100 * BRIDGE_SPAN[0]:.0f}-{100 * BRIDGE_SPAN[1]:.0f} cm apart along y, "
                        f"within {100 * ALIGN:.0f} cm across")


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
            span, a, b = names
            side = "right" if objects[b].position[1] > objects[a].position[1] else "left"
            actions.append(Action(span, "center", a, side))
        else:  # a row: each released beside the one before, coming down on the table
            actions += [Action(names[i + 1], "center", names[i], "right")
                        for i in range(len(names) - 1)]
    return actions


TASKS = ("tower", "row", "towers")  # `problems make --task`: what a random goal builds


def sample_structures(rng: np.random.Generator, objects: dict[str, ObjectState], task: str,
                      k: int) -> list[Structure] | str:
    """A random goal of `task` that takes `k` actions to build from `objects`: a tower of
    k + 1 boxes, a row of k + 1 cubes, or two towers of k + 2 boxes; or why the scene
    cannot give one (a string)."""
    names = [str(n) for n in rng.permutation(sorted(objects))]
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
