"""What rests on what, and the goal relations a person names: one geometry, one set of
tolerances, for the skills, the continuous model and its stability rules (through
continuous.Boxes.object_states), the agent, evaluation and the goal compiler.

Boxes are ObjectStates (name, type, centre, yaw, tilt), from a scene file, from perception
or predicted. `top` is the height of a box's top face; `rests_on(a, b)` says that a's
bottom meets b's top with a's centre over b's footprint; `riders` are the boxes resting on
one, and on those, and so on. The goal relations, as one-line specs:

    on A B             A rests on B, upright
    tower A B ... Z    each on the next (Z anywhere)
    bridge L A B       the long block L bears on both A and B (its footprint over each top)
    row A B ... Z      on the table, each beside the one before along +y (a gap of at most
                       ROW_GAP between their faces), aligned across within ALIGN

`unmet(relations, objects)` is the check: what does not hold, one line each; it holds
wherever the structure stands. No Drake and no torch here.
"""

from __future__ import annotations

import dataclasses as dc
from collections import Counter
from collections.abc import Iterable, Mapping

import numpy as np

from drake_symplan.boxes import HALF_EXTENTS
from drake_symplan.datasets import ObjectState

REST_TOL = 0.015  # m: a box whose bottom is this near another's top rests on it
FOOTPRINT_TOL = 0.01  # m outside a footprint that still counts as over it
BEAR_OVERLAP = 0.01  # m: a bridge's span overlaps each support's top by at least this
TABLE_TOL = 0.01  # m: a box whose bottom is this near the table stands on it
UPRIGHT = 0.2  # rad: a box tilted more than this is on nothing, in a goal's sense
ALIGN = 0.02  # m: a row's members (and a bridge's supports) this near each other across y
ROW_GAP = 0.05  # m: at most this between the faces of a row's neighbours along y

ARITY = {"on": (2, 2), "tower": (2, None), "bridge": (3, 3), "row": (2, None)}
# The kind of pair (Relation.pairs) each word names, which `pair_unmet` checks.
PAIR_KIND = {"on": "on", "tower": "on", "bridge": "bears", "row": "beside"}
PAIR_KINDS = ("on", "bears", "beside")


class SpecError(ValueError):
    """A spec the world cannot satisfy, with why (one line)."""


@dc.dataclass(frozen=True)
class Relation:
    """One structure a goal names: its word (ARITY's keys) and objects, in spec order."""

    word: str
    objects: tuple[str, ...]

    def text(self) -> str:
        return " ".join((self.word, *self.objects))

    def pairs(self) -> tuple[tuple[str, str], ...]:
        """The (upper, lower) or (first, next) pairs the relation is about."""
        o = self.objects
        if self.word == "bridge":
            return ((o[0], o[1]), (o[0], o[2]))
        return tuple(zip(o, o[1:], strict=False))


def brief(text: str, most: int = 60) -> str:
    """`text` quoted, cut to `most` characters (a spec in a one-line message)."""
    return repr(text if len(text) <= most else text[:most] + " ...")


def listed(names: list[str], most: int = 5) -> str:
    """Names joined by commas, the first `most` and how many more."""
    more = f" and {len(names) - most} more" if len(names) > most else ""
    return ", ".join(names[:most]) + more


def parse(specs: Iterable[str]) -> list[Relation]:
    """Relations of one-line specs ('tower o3 o1 o0', ...); SpecError on a bad word, a
    wrong count or a name twice in one spec."""
    out = []
    for spec in specs:
        words = spec.split()
        if not words:
            raise SpecError("an empty spec")
        word, names = words[0], tuple(words[1:])
        if word not in ARITY:
            raise SpecError(f"{brief(spec)}: unknown word {brief(word, 20)}; expected one of "
                            f"{sorted(ARITY)}")
        low, high = ARITY[word]
        if len(names) < low or (high is not None and len(names) > high):
            count = f"{low}" if low == high else f"at least {low}"
            raise SpecError(f"{brief(spec)}: {word} takes {count} objects, got {len(names)}")
        twice = sorted(n for n, times in Counter(names).items() if times > 1)
        if twice:
            raise SpecError(f"{brief(spec)}: {listed(twice)} named twice")
        out.append(Relation(word, names))
    return out


def named(relations: Iterable[Relation]) -> list[str]:
    """The objects the relations name, each once, in order."""
    return list(dict.fromkeys(n for r in relations for n in r.objects))


# --- one geometry ---------------------------------------------------------------------

def top(o: ObjectState) -> float:
    """The height of `o`'s highest point (its top face when upright)."""
    hx, hy, hz = HALF_EXTENTS[o.type]
    return float(o.position[2] + hz * np.cos(o.tilt) + max(hx, hy) * abs(np.sin(o.tilt)))


def bottom(o: ObjectState) -> float:
    """The height of an upright `o`'s bottom face."""
    return float(o.position[2] - HALF_EXTENTS[o.type][2])


def turn(v: np.ndarray, yaw: float) -> np.ndarray:
    """The xy vector `v` turned by `yaw` about world z."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def local_xy(o: ObjectState, p: np.ndarray) -> np.ndarray:
    """World point `p` (xy) in `o`'s frame (xy)."""
    return turn(np.asarray(p[:2], float) - o.position[:2], -o.yaw)


def covers(o: ObjectState, p: np.ndarray, tol=FOOTPRINT_TOL) -> bool:
    """Does `o`'s footprint, grown by `tol` (m, or per local axis), hold the xy point `p`?"""
    return bool(np.all(np.abs(local_xy(o, p)) <= np.array(HALF_EXTENTS[o.type][:2]) + tol))


def meets_at(upper_type: str, upper_z: float, lower_type: str, lower_z: float) -> bool:
    """Does the bottom of an upright box of `upper_type` centred at height `upper_z` meet
    the top of one of `lower_type` centred at `lower_z` (within REST_TOL)? `meets` on
    heights alone, for a goal of positions (abstraction/goal_order.py)."""
    gap = (upper_z - HALF_EXTENTS[upper_type][2]) - (lower_z + HALF_EXTENTS[lower_type][2])
    return abs(gap) <= REST_TOL


def meets(upper: ObjectState, lower: ObjectState) -> bool:
    """Does `upper`'s bottom meet `lower`'s top (within REST_TOL)?"""
    return meets_at(upper.type, upper.position[2], lower.type, lower.position[2])


def rests_on(upper: ObjectState, lower: ObjectState) -> bool:
    """Does `upper` rest on `lower`: its bottom on `lower`'s top, its centre over it?"""
    return meets(upper, lower) and covers(lower, upper.position)


def bears_on(span: ObjectState, support: ObjectState) -> bool:
    """Does `span` bear on `support`: its bottom on the support's top, its footprint over
    it by BEAR_OVERLAP (a 5 x 5 grid of the support's top inside the span's footprint)?"""
    if not meets(span, support):
        return False
    h = np.array(HALF_EXTENTS[support.type][:2]) - BEAR_OVERLAP
    u = np.linspace(-1.0, 1.0, 5)
    grid = [support.position[:2] + turn(np.array([a * h[0], b * h[1]]), support.yaw)
            for a in u for b in u]
    return any(covers(span, p, 0.0) for p in grid)


def on_table(o: ObjectState) -> bool:
    return bottom(o) <= TABLE_TOL


def riders(source: str, objects: Mapping[str, ObjectState]) -> list[str]:
    """The boxes resting on `source`, and on those, and so on (rests_on)."""
    found, frontier = [], [source]
    while frontier:
        below = objects[frontier.pop()]
        for name, o in objects.items():
            if name != source and name not in found and rests_on(o, below):
                found.append(name)
                frontier.append(name)
    return found


def half_along_y(o: ObjectState) -> float:
    """Half of `o`'s footprint's extent along world y."""
    hx, hy, _ = HALF_EXTENTS[o.type]
    return float(abs(np.sin(o.yaw)) * hx + abs(np.cos(o.yaw)) * hy)


# --- the goal relations ------------------------------------------------------------------

def _upright(o: ObjectState) -> bool:
    return abs(o.tilt) <= UPRIGHT


def _row_pair(first: ObjectState, second: ObjectState) -> str | None:
    if not (on_table(first) and on_table(second) and _upright(first) and _upright(second)):
        return f"{first.name} and {second.name} do not both stand on the table"
    d = second.position[:2] - first.position[:2]
    gap = d[1] - half_along_y(first) - half_along_y(second)
    if abs(d[0]) > ALIGN or not -REST_TOL <= gap <= ROW_GAP:
        return (f"{second.name} is not beside {first.name} along +y (gap {100 * gap:.1f} cm, "
                f"{100 * abs(d[0]):.1f} cm across)")
    return None


def pair_unmet(kind: str, first: ObjectState, second: ObjectState) -> str | None:
    """None if the pair (first, second), as Relation.pairs orders it, is of `kind`
    (PAIR_KINDS): first on second, upright; first bearing on second; second beside first
    in a row. Else what does not hold (one line)."""
    if kind == "beside":
        return _row_pair(first, second)
    if kind == "bears":
        return None if bears_on(first, second) else \
            f"{first.name} does not bear on {second.name}"
    if kind == "on":
        return None if _upright(first) and rests_on(first, second) else \
            f"{first.name} is not on {second.name}"
    raise ValueError(f"unknown pair kind {kind!r}; one of {PAIR_KINDS}")


def unmet_one(relation: Relation, objects: Mapping[str, ObjectState]) -> str | None:
    """None if `objects` hold `relation`, else what does not hold (one line)."""
    missing = [n for n in relation.objects if n not in objects]
    if missing:
        return f"{', '.join(missing)} not seen"
    for first, second in relation.pairs():
        wrong = pair_unmet(PAIR_KIND[relation.word], objects[first], objects[second])
        if wrong:
            return wrong
    return None


def holding(relations: Iterable[Relation], objects: Mapping[str, ObjectState]) -> set[str]:
    """The boxes of the relations' pairs that `objects` hold already: where a part of the
    goal stands. A box named only in pairs that do not hold yet may stand anywhere."""
    out = set()
    for r in relations:
        for first, second in r.pairs():
            if first in objects and second in objects and pair_unmet(
                    PAIR_KIND[r.word], objects[first], objects[second]) is None:
                out |= {first, second}
    return out


def unmet(relations: Iterable[Relation], objects: Mapping[str, ObjectState]) -> list[str]:
    """What of `relations` the boxes `objects` (by name) do not hold, one line each; empty:
    the goal holds."""
    out = []
    for r in relations:
        wrong = unmet_one(r, objects)
        if wrong is not None:
            out.append(f"{r.text()!r}: {wrong}")
    return out
