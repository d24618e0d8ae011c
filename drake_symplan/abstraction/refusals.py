"""What the planner knows of what the arm will not run: the grasps the arm's own rule
refuses in a scene (a stack it will not lift), and the steps it refused in this solve, by
the side it refused at and the boxes it named in its way. Rules on the believed and
predicted boxes only (abstraction/bilevel.py's Refiner asks them); no simulator.

A refusal key is (side, box, offset): ("grasp", source, grasp) bars that source at that
grasp; ("release", target, release) bars setting anything down on that target at that
release offset (the arm's wrist would strike a box beside the target, whatever it holds).
"""

from __future__ import annotations

import numpy as np

from drake_symplan.abstraction.continuous import MOVED, Boxes
from drake_symplan.actions import OFFSETS, Action

Key = tuple[str, str, str]


def refusal(action: Action, at: str) -> Key:
    """What a refusal of `action` bars: at its release ("release"), placing on its target
    at that release offset, whatever the source; else its source at that grasp."""
    if at == "release":
        return ("release", action.target, action.release)
    return ("grasp", action.source, action.grasp)


def allows(action: Action, barred: set[Key]) -> bool:
    """Does no key in `barred` (Refusals.barred) bar `action`, at its grasp or release?"""
    return refusal(action, "grasp") not in barred and refusal(action, "release") not in barred


class Refusals:
    """The refusals of one solve: `keys`, refused in the scene as it stands (the agent's
    mode forgets those near a box that moved: planning_modes.NEAR), and `blockers`, per
    key the boxes the arm named in its way, where they were seen. In a predicted scene a
    refusal lifts where one of its blockers is predicted moved (beyond MOVED)."""

    def __init__(self):
        self.keys: set[Key] = set()
        self.blockers: dict[Key, dict[str, np.ndarray]] = {}

    def refuse(self, action: Action, obstacles: dict[str, np.ndarray] | None = None,
               at: str = "") -> None:
        """The arm refused `action` in the scene seen now, `at` its grasp (the default) or
        its release; `obstacles`: the boxes in its way there, by where they were seen."""
        key = refusal(action, at)
        self.keys.add(key)
        if obstacles:
            self.blockers[key] = dict(obstacles)

    def keep(self, keys: set[Key]) -> None:
        """Only `keys` stand (with their blockers)."""
        self.keys = set(keys)
        self.blockers = {k: v for k, v in self.blockers.items() if k in self.keys}

    def cleared(self, where: dict[str, np.ndarray]) -> set[Key]:
        """The refusals one of whose blockers is predicted moved (`where`: positions)."""
        return {key for key, boxes in self.blockers.items()
                if any(n in where and np.linalg.norm(where[n] - p) > MOVED
                       for n, p in boxes.items())}

    def in_the_way(self, boxes: Boxes) -> set[str]:
        """The boxes in the way of a refusal that still stand where they were seen in
        `boxes`: the search asks for their moves first."""
        cleared = self.cleared(boxes.where())
        return {n for key in self.keys - cleared for n in self.blockers.get(key, {})}

    def barred(self, boxes: Boxes) -> set[Key]:
        """The keys no step from `boxes` takes (`allows`): the refusals standing there, and
        the grasps the arm would refuse there by its own rule, under a stack it will not
        lift (skills/carry.unpinchable, with the skill's own riders and tolerances)."""
        # The skill's rule on beliefs (Drake-free), imported here: importing the planner
        # loads no skill.
        from drake_symplan.skills.carry import unpinchable

        out = self.keys - self.cleared(boxes.where())
        objects = boxes.object_states()
        for source in boxes.names:
            target = next(n for n in boxes.names if n != source)
            out |= {("grasp", source, g) for g in OFFSETS
                    if unpinchable(Action(source, g, target, "center"), objects)}
        return out
