"""A goal of relations' example positions moved to where its structures stand: the
continuous search's guidance towards a goal that holds wherever it stands.

The search ranks scenes by their boxes' distances to goal positions (refiner.py). For a
goal of relations those are the example's (the compiled goal scene), one place of many
where the structures would hold. Once a structure has begun elsewhere (built there by an
earlier plan, or knocked and rebuilt), the example's positions say each of its boxes is
far off and ask to move them back, and the search wanders. So each structure (the boxes
the named pairs connect) is anchored where it has begun: its example positions moved
across the table with its lowest box (the first named of those as low) where a box of a
pair on it stands set as in the example. A structure not begun so keeps the example's
places, which the goal's author checked have room: a stack standing apart from the box
it goes on is carried there, not built under. Heights stay the example's.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np

from drake_symplan.relations import named

HELD = 0.03  # m: a pair whose boxes stand this near their example offset has begun there


def structures(relations: Iterable, goal: Mapping[str, np.ndarray]) -> list[tuple[str, ...]]:
    """The named boxes of `relations` in `goal`, grouped by the pairs that connect them
    (relations.Relation.pairs), each group led by its anchor: the box lowest in the
    example, the first named of those as low."""
    relations = list(relations)
    order = [n for n in named(relations) if n in goal]
    part = {n: n for n in order}

    def root(n: str) -> str:
        while part[n] != n:
            n = part[n]
        return n

    for r in relations:
        for a, b in r.pairs():
            if a in part and b in part:
                part[root(a)] = root(b)
    groups: dict[str, list[str]] = {}
    for n in order:
        groups.setdefault(root(n), []).append(n)
    return [tuple(sorted(g, key=lambda n: (round(float(goal[n][2]), 3), order.index(n))))
            for g in groups.values()]


class AnchoredGoal:
    """The goal positions a scene is guided towards (module docstring): `at(where)`."""

    def __init__(self, relations: Iterable, goal: Mapping[str, np.ndarray]):
        self.goal = {n: np.asarray(p, float) for n, p in goal.items()}
        relations = list(relations)
        self.parts = [(part, [(a, b) for r in relations for a, b in r.pairs()
                               if a in part and b in part])
                      for part in structures(relations, self.goal)]  # (boxes, pairs)

    def at(self, where: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The goal positions for the boxes standing at `where` (by name): per structure
        begun somewhere (a box set on or beside its lowest as in the example, within
        HELD), the example's moved across the table with that box; else the example's
        (`goal` itself where no structure has begun)."""
        out = self.goal
        for part, pairs in self.parts:
            anchor = part[0]
            if any(lower == anchor and self._held(upper, lower, where) for upper, lower in pairs):
                shift = np.zeros(3)
                shift[:2] = where[anchor][:2] - self.goal[anchor][:2]
                out = dict(out) if out is self.goal else out
                out.update({n: self.goal[n] + shift for n in part})
        return out

    def _held(self, upper: str, lower: str, where: Mapping[str, np.ndarray]) -> bool:
        """Does `upper` stand off `lower` as in the example, within HELD?"""
        offset = (where[upper] - where[lower]) - (self.goal[upper] - self.goal[lower])
        return float(np.linalg.norm(offset)) <= HELD


