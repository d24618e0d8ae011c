"""Test aids for bilevel planning's tests: a three-cube stacking domain, fake models, `solve`."""

from __future__ import annotations

import numpy as np
import torch

from drake_symplan.abstraction.abstraction import Observation, Plan
from drake_symplan.abstraction.bilevel import Search, plan_bilevel
from drake_symplan.abstraction.continuous import Boxes
from drake_symplan.abstraction.refiner import Refiner
from drake_symplan.actions import Action, release_shift
from drake_symplan.features import object_features
from drake_symplan.planning.budget import Budget
from drake_symplan.symbolic.structs import LiftedOperator, Step

ON = (("on", 0, 1),)
STACK = {r: LiftedOperator(i, "center", r, 2, (), ON, (), 10, 10, 10)
         for i, r in enumerate(("center", "left", "right"))}


def boxes(**where) -> Boxes:
    """Cubes at the given (x, y, z) positions."""
    names = tuple(where)
    features = np.stack([object_features("cube", np.array(p, float), np.eye(3))
                         for p in where.values()])
    return Boxes(names, features, frozenset()).moved(features[:, :3])


class Stacking:
    """The hand-written world model: the source lands on the target's top, shifted by the
    offsets (actions.release_shift); nothing else moves."""

    def predict(self, scene: Boxes, actions: list[Action]) -> list[Boxes]:
        out = []
        for a in actions:
            pos = scene.positions.astype(float).copy()
            i, j = scene.names.index(a.source), scene.names.index(a.target)
            pos[i] = pos[j] + [0.0, release_shift(a), 0.05]
            out.append(scene.moved(pos))
        return out


class Skeletons:
    """An abstraction whose symbolic planner returns the given plans, in turn."""

    def __init__(self, *plans):
        self.plans = list(plans)

    def plan(self, start, goal, planner, budget, focus=True, penalties=None, unheld=frozenset()):
        return self.plans.pop(0) if self.plans else Plan("unsolvable")

    def believed(self, reading):
        return frozenset()

    def goal_atoms(self, reading):
        return frozenset()


START = boxes(a=(0.5, 0.2, 0.025), b=(0.5, -0.2, 0.025), c=(0.7, 0.0, 0.025))


def observed(scene: Boxes) -> Observation:
    """A scene as planning gets it, its boxes alone (the fakes read no symbols)."""
    return Observation(None, None, scene)


def solve(abstraction, goal: Boxes, extra_moves=0, skeletons=True, alternatives=0,
          horizon=None, penalties=None):
    refiner = Refiner(list(STACK.values()), Stacking(), extra_moves=extra_moves)
    return plan_bilevel(abstraction, refiner, observed(START), observed(goal),
                        Budget(10.0, 30.0), Search(skeletons, alternatives=alternatives,
                                                   horizon=horizon), penalties)


class Penalized(Skeletons):
    """A symbolic planner that puts a on b unless that move is made dearer, then a on c."""

    def __init__(self):
        super().__init__()
        self.asked = []

    def plan(self, start, goal, planner, budget, focus=True, penalties=None, unheld=frozenset()):
        self.asked.append(dict(penalties or {}))
        target = "c" if ("a", "b") in (penalties or {}) else "b"
        return Plan("solved", [Step(STACK["center"], ("a", target))])


class Lifting(torch.nn.Module):
    """An effect model that says: the source rises 10 cm at the lift and comes down 5 cm
    above where the carry put it; the target and the rest do not move."""

    def forward(self, state, action, mask):
        effect = torch.zeros(*state.shape[:2], 6)
        source = action[:, :, 0] > 0.5
        effect[source] = torch.tensor([0.0, 0.0, 0.10, 0.0, 0.0, -0.05])
        return effect


TOWER = boxes(a=(0.7, 0.0, 0.075), b=(0.7, 0.0, 0.125), c=(0.7, 0.0, 0.025))
