"""How the agent gets its plan (SolveConfig.planning): from the symbols alone, bilevel
(skeletons refined with the learned continuous model), in continuous space alone, or, for
the evaluation's oracle row, replayed from the actions that made the problem.

`Planner.plan(now, goal, now_scene, goal_scene)` returns an abstraction.Plan; `departs`
says whether what is perceived after a step has left the plan's prediction (the monitor
then replans): the symbols against the step's operator for symbolic plans, the perceived
positions against the predicted ones (DEVIATION) for plans checked in continuous space.
"""

from __future__ import annotations

import numpy as np
import torch

from drake_symplan.abstraction.abstraction import Abstraction, Plan, Reading
from drake_symplan.abstraction.bilevel import Budget, Refiner, plan_bilevel, reaches_goal
from drake_symplan.abstraction.continuous import Boxes, ContinuousModel
from drake_symplan.actions import Action
from drake_symplan.agent.config import SolveConfig
from drake_symplan.boxes import GOAL_TOLERANCE
from drake_symplan.planning.planners import WALL_FACTOR
from drake_symplan.symbolic.structs import PlanStep, Reposition, reaches

# m: a box perceived this far from its predicted position (beyond the prediction's spread)
# departs the plan
DEVIATION = 0.03


class Planner:
    """The agent's planning for one solve (module docstring); `given`: the replayed plan
    of the oracle mode."""

    def __init__(self, abstraction: Abstraction, config: SolveConfig,
                 given: list[Action] | None = None):
        self.abs, self.config = abstraction, config
        self.given = given
        self.level = "symbolic"  # of the plan returned last
        self.refiner = None
        # The networks see batches of tens of actions, where more threads spin more than
        # they compute: one thread makes 1.2x the predictions per CPU second of torch's
        # default on a quiet 2-core host, up to 7x beside other work (tools/bench_search.py).
        torch.set_num_threads(1)
        if config.planning in ("bilevel", "continuous"):
            self.refiner = Refiner(abstraction.bundle.operators,
                                   ContinuousModel(abstraction.bundle.continuous))

    def plan(self, now: Reading, goal: Reading, now_scene, goal_scene) -> Plan:
        found = self._plan(now, goal, now_scene, goal_scene)
        self.level = found.level
        return found

    def _plan(self, now: Reading, goal: Reading, now_scene, goal_scene) -> Plan:
        mode = self.config.planning
        if mode == "oracle":
            if self.given is None:
                raise ValueError("the oracle replays a problem's recorded actions; none given")
            return Plan("solved", [Reposition(a, "move") for a in self.given], 0.0, "",
                        "oracle", level="oracle")
        cpu, wall = self.config.timeout, WALL_FACTOR * self.config.timeout
        if mode == "symbolic":
            return self.abs.plan(now, goal, self.config.planner, wall, cpu_seconds=cpu)
        return plan_bilevel(self.abs, self.refiner, now, goal, Boxes.of(now_scene),
                            Boxes.of(goal_scene), mode, self.config.planner, cpu,
                            Budget(cpu, wall), self.config.alternatives)

    @property
    def predicts_positions(self) -> bool:
        """Was the last plan checked in continuous space (else: on its symbols)?"""
        return self.level in ("bilevel", "continuous", "nearest")

    def departs(self, step: PlanStep, predicted: Boxes | None, seen: Reading, seen_scene,
                rest: list[PlanStep], believed, goal_atoms, goal_scene=None) -> bool:
        """Has the scene perceived after `step` left the plan? A plan checked in continuous
        space has left it when a box is off its predicted position and the rest of the
        plan, predicted again from what is seen, no longer reaches the goal (a small
        miss that the rest absorbs costs no replan); at its end the goal check decides."""
        if self.predicts_positions:
            if predicted is None or not rest:
                return False
            where = predicted.where()
            spread = dict(zip(predicted.names, predicted.uncertainty(), strict=True))
            off = any(np.linalg.norm(o.position - where[o.name]) > DEVIATION + spread[o.name]
                      for o in seen_scene.objects if o.name in where)
            if not off or goal_scene is None:
                return off
            end = self.refiner.rollout(Boxes.of(seen_scene), rest)
            return not reaches_goal(end, Boxes.of(goal_scene).where(), self.refiner.limit)
        if isinstance(step, Reposition):  # no symbolic prediction: the rest must apply
            return not reaches(rest, believed, goal_atoms)
        return bool(self.abs.mismatches(seen, step))

    def goal_seen(self, reading: Reading, goal_atoms, scene, goal_scene) -> bool:
        """At the plan's end: the goal's atoms seen (symbolic planning), or every box seen
        within the tolerance of its goal (bilevel and continuous planning: also after a
        skeleton that ran on its symbols, whose atoms can hold with a box far off)."""
        if self.config.planning == "symbolic":
            return self.abs.goal_holds(reading, goal_atoms)
        return reaches_goal(Boxes.of(scene), Boxes.of(goal_scene).where(), GOAL_TOLERANCE)
