"""What the planner knows of what the arm will not run: the grasps the arm's own rules
refuse in a scene (a stack it will not lift, a box its palm would strike), the releases
that would drive a box into another, and the steps it refused in this solve, by the side
it refused at and the boxes it named in its way. Rules on the believed and predicted
boxes only (abstraction/refiner.py's Refiner asks them); no simulator.

A refusal key is (side, box, offset): ("grasp", source, grasp) bars that source at that
grasp; ("release", target, release) bars setting anything down on that target at that
release offset (the arm's wrist would strike a box beside the target, whatever it holds).
"""

from __future__ import annotations

import numpy as np

from drake_symplan.abstraction.continuous import MOVED, Boxes
from drake_symplan.actions import OFFSETS, Action, grasp_on_box

Key = tuple[str, str, str]
GRID = 0.005  # m (and rad): scenes whose boxes near a source agree this far share its grasps


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
        self._grasps: dict[tuple, bool] = {}  # the arm's rules on a grasp, by GRID key

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

    def barred(self, boxes: Boxes, sources=None) -> set[Key]:
        """The keys no step from `boxes` takes (`allows`): the refusals standing there, and
        the grasps the arm would refuse there by its own rules, under a stack it will not
        lift (skills/carry.unpinchable, with the skill's own riders and tolerances) or
        where its palm or wrist would strike a box (skills/geometry.grasp_struck); the grasps of
        `sources` only where given (the rules take 40 % of a search that asks all)."""
        # The skill's rules on beliefs, imported here: importing the planner loads no skill.
        from drake_symplan.skills.geometry import grasp_refused, palm_reach

        out = self.keys - self.cleared(boxes.where())
        objects = boxes.object_states()
        for source in boxes.names if sources is None else sorted(sources):
            target = next(n for n in boxes.names if n != source)
            # the arm's answer depends only on the source and the boxes near it (its
            # riders among them; with none near it lifts it): kept for the scenes the
            # search predicts with them where they were (GRID)
            near = palm_reach(source, objects)
            if not near:
                continue
            key = tuple((n, *np.round(np.r_[objects[n].position, objects[n].yaw] / GRID))
                        for n in (source, *near))
            for g in (g for g in OFFSETS if grasp_on_box(g, boxes.half_length(source))):
                if self._refused(key + (g,), Action(source, g, target, "center"), objects,
                                 grasp_refused):
                    out.add(("grasp", source, g))
        return out

    @staticmethod
    def crowding(boxes: Boxes, sources) -> set[str]:
        """The boxes near `sources` that the palm could strike coming down to grasp them
        (skills/geometry.palm_reach): where the arm's rules bar every grasp of a source,
        what the search moves out of its way first."""
        from drake_symplan.skills.geometry import palm_reach

        objects = boxes.object_states()
        return {n for s in sources for n in palm_reach(s, objects)} - set(sources)

    def release_refused(self, boxes: Boxes, action: Action) -> bool:
        """Would `action`'s release in `boxes` be refused: its source driven into a box,
        which the arm refuses (skills/geometry.set_down_struck: a block set on a cube
        beside a taller tower), or set down out of the cameras' view, which the agent
        refuses (set_down_unseen)?"""
        from drake_symplan.skills.geometry import release_refused

        return release_refused(action, boxes.object_states())

    def _refused(self, key, action: Action, objects, grasp_refused) -> bool:
        if key not in self._grasps:
            self._grasps[key] = grasp_refused(action, objects)
        return self._grasps[key]
