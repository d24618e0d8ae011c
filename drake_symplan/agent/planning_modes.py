"""How the agent gets its plan (SolveConfig.planning, `--planning`): one class per planning
mode, all in the PLANNING_MODES registry, which the CLI's choices, SolveConfig's check,
the evaluation and the reproduction read.

- `bilevel` (the default): the symbolic planner's skeletons refined with the learned
  continuous model, its search as the fallback (abstraction/bilevel.py, refiner.py);
- `symbolic`: plans from the symbols alone;
- `receding`: bilevel over a receding horizon: a skeleton longer than HORIZON steps is
  refined only over its first steps, to its subgoal, and the agent plans again from what
  it sees after them (abstraction/bilevel.py);
- `continuous`: the continuous model's search alone;
- `oracle`: the problem's recorded actions replayed open loop, the evaluation's ceiling.

A mode is made per solve, `make_planner(abstraction, config, given)`. `plan(now, goal)`
plans from one perceived abstraction.Observation to another and returns an
abstraction.Plan, whose level says whether it was checked in continuous space (Plan's
`predicts_positions`, abstraction.LEVELS); `departs` says whether what is perceived after
a step has left the plan (the monitor then replans): the perceived positions against the
predicted ones (DEVIATION) for a plan checked in continuous space, else the symbols against
the step's operator; `goal_seen` is the monitor's check at the plan's end.

A mode's flags say what the rest of the agent needs to know of it: `needs_refiner` (it
plans with the learned continuous model), `needs_recorded_actions` (it replays the
problem's own actions: only `eval planning` has them, so `solve` does not offer it),
`open_loop_only` (evaluated open loop only), `reproduced` (a row of `symplan
reproduce`). A new mode is a PlanningMode subclass (here or in a module beside it) and
its entry in PLANNING_MODES.

Importing this module loads no torch (SolveConfig and the CLI read the registry): the
learned models' modules are imported when a mode is made.
"""

from __future__ import annotations

from collections import Counter
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from drake_symplan.boxes import goal_distances, goal_reached
from drake_symplan.planning.budget import Budget
from drake_symplan.relations import unmet
from drake_symplan.symbolic.structs import PlanStep, Reposition, Step, reaches

if TYPE_CHECKING:
    from drake_symplan.abstraction.abstraction import Abstraction, Observation, Plan
    from drake_symplan.abstraction.continuous import Boxes
    from drake_symplan.actions import Action
    from drake_symplan.agent.config import SolveConfig

# m: a box perceived this far from its predicted position (beyond the prediction's spread)
# departs the plan
DEVIATION = 0.03
# m: after a step that moved no box farther than this (perceived), the arm achieved nothing:
# the same action on the same scene would do the same, so it counts as missed
STILL = 0.015
# Steps of a longer skeleton the receding mode refines before it looks and plans again: the
# learned model predicts one action to 1.5 cm (mean, held out) and five to 9 cm (README).
HORIZON = 1


# A refused grasp stands until a box this near its source (xy, m) moves: the arm's wrist
# reaches 21 cm beside the tool axis, and a grasp is up to 10 cm from the source's centre.
NEAR = 0.30


def moved(before: Observation, seen: Observation) -> set[str]:
    """The boxes seen more than STILL from where they were seen before the step."""
    then = before.boxes.where()
    return {n for n, p in seen.boxes.where().items()
            if n in then and np.linalg.norm(p - then[n]) > STILL}


def near_moved(box: str, then: dict[str, np.ndarray], shifted: set[str]) -> bool:
    """Has a box within NEAR (xy) of `box` moved (`shifted`), by where they were seen
    before the step (`then`, which has `box`)? A refusal then no longer stands."""
    return any(np.linalg.norm((then[m] - then[box])[:2]) <= NEAR for m in shifted)


def off_prediction(predicted: Boxes, seen: Observation) -> bool:
    """Is a box seen off its predicted position by more than DEVIATION beyond the
    prediction's spread?"""
    where = predicted.where()
    spread = dict(zip(predicted.names, predicted.uncertainty(), strict=True))
    return any(np.linalg.norm(o.position - where[o.name]) > DEVIATION + spread[o.name]
               for o in seen.scene.objects if o.name in where)


class PlanningMode:
    """One solve's planning (module docstring); `given`: the actions a mode that
    `needs_recorded_actions` replays."""

    name: ClassVar[str]
    help: ClassVar[str]  # for --planning
    needs_refiner: ClassVar[bool] = False
    needs_recorded_actions: ClassVar[bool] = False
    open_loop_only: ClassVar[bool] = False
    reproduced: ClassVar[bool] = True  # a row of `symplan reproduce`'s mode table

    def __init__(self, abstraction: Abstraction, config: SolveConfig,
                 given: list[Action] | None = None):
        import torch  # here, not at the top: see the module docstring

        self.abs, self.config, self.given = abstraction, config, given
        self.last: Plan | None = None  # the plan returned last
        self.refiner = None
        # The networks see batches of tens of actions, where more threads spin more than
        # they compute: one thread makes 1.2x the predictions per CPU second of torch's
        # default on a quiet 2-core host, up to 7x beside other work (tools/bench_search.py).
        torch.set_num_threads(1)

    def plan(self, now: Observation, goal: Observation) -> Plan:
        self.last = self._plan(now, goal)
        return self.last

    def _plan(self, now: Observation, goal: Observation) -> Plan:
        raise NotImplementedError

    def budget(self) -> Budget:
        """One plan's budget: the config's CPU seconds, from now."""
        return Budget.of_cpu(self.config.cpu_seconds)

    @property
    def predicts_positions(self) -> bool:
        """Was the last plan checked in continuous space (else: on its symbols)?"""
        return self.last is not None and self.last.predicts_positions

    @property
    def subgoal_plan(self) -> bool:
        """Does the last plan end at a subgoal, where the agent plans on (Plan.subgoal)?"""
        return self.last is not None and self.last.subgoal

    @property
    def symbolic_plan(self) -> bool:
        """Is the last plan one on symbols alone, which the agent completes as it runs
        (its offsets, abstraction/offsets.py; repositionings, agent/reposition.py)?"""
        return self.last is None or self.last.symbolic

    def departs(self, step: PlanStep, predicted: Boxes | None, seen: Observation,
                rest: list[PlanStep], believed, goal_atoms, goal: Observation | None = None
                ) -> bool:
        """Has the scene `seen` after `step` left the plan? A plan on symbols: the step's
        operator's prediction did not come true and the rest of the plan no longer
        reaches the goal's atoms from what is seen (a miss the rest absorbs, a bit the
        plan does not ask for, costs no replan); a repositioning, which predicts
        nothing: the rest no longer applies."""
        if isinstance(step, Step) and not self.abs.mismatches(seen.reading, step):
            return False
        return not reaches(rest, believed, goal_atoms)

    def observed(self, step: PlanStep, predicted: Boxes | None, before: Observation,
                 seen: Observation) -> None:
        """Told what was seen `before` and after each step the monitor checks (what a
        mode learns within a solve; none by default)."""

    def refused(self, step: PlanStep, obstacles: dict[str, np.ndarray] | None = None,
                at: str = "") -> None:
        """Told that the arm could not run `step` from the scene seen now (an unreachable
        pose, a box its wrist would strike; `obstacles`: those boxes, where they are seen;
        `at`: "grasp" or "release", the side it refused at): the agent plans again from the
        same scene."""

    def goal_seen(self, seen: Observation, goal_atoms, goal: Observation) -> bool:
        """At the plan's end: every box seen within the tolerance of its goal (also after
        a skeleton that ran on its symbols, whose atoms can hold with a box far off); a
        goal of relations: its relations seen to hold (relations.unmet)."""
        if goal.relations:
            return not unmet(goal.relations, seen.scene.object_states())
        return goal_reached(goal_distances(seen.boxes.where(), goal.boxes.where()))


class SymbolicMode(PlanningMode):
    name = "symbolic"
    help = "plans from the symbols alone"

    def __init__(self, abstraction: Abstraction, config: SolveConfig,
                 given: list[Action] | None = None):
        super().__init__(abstraction, config, given)
        # costs added to the moves of (source, target, ...) the arm missed in this solve,
        # and to those it refused in the scene as it stands, so that the planner tries
        # another way while one is left
        self.penalties: Counter = Counter()
        self.refusals: Counter = Counter()

    def _plan(self, now: Observation, goal: Observation) -> Plan:
        from drake_symplan.abstraction.relation_goal import unheld_in

        return self.abs.plan(now.reading, goal.reading, self.config.planner, self.budget(),
                             penalties=dict(self.penalties + self.refusals),
                             unheld=unheld_in(now, goal))

    def refused(self, step: PlanStep, obstacles: dict[str, np.ndarray] | None = None,
                at: str = "") -> None:
        """A step the arm would not run costs more in the plans after it, until a box
        within NEAR of its source has moved (as in bilevel planning)."""
        from drake_symplan.abstraction.bilevel import PENALTY

        if isinstance(step, Step):
            self.refusals[tuple(step.args)] += PENALTY

    def observed(self, step: PlanStep, predicted: Boxes | None, before: Observation,
                 seen: Observation) -> None:
        """A step after which nothing moved (the arm achieved nothing: the same step on
        the same scene would do the same) costs more in the plans after it; a refusal
        near a box that moved is forgotten (the arm may run its step now: a row's box
        refused beside the next one before that one moved was later laid elsewhere)."""
        from drake_symplan.abstraction.bilevel import PENALTY

        then, shifted = before.boxes.where(), moved(before, seen)
        for key in [k for k in self.refusals if k[0] in then
                    and near_moved(k[0], then, shifted)]:
            del self.refusals[key]
        if isinstance(step, Step) and not shifted:
            self.penalties[tuple(step.args)] += PENALTY

    def goal_seen(self, seen: Observation, goal_atoms, goal: Observation) -> bool:
        """At the plan's end: the goal's atoms seen (the planner's own criterion), and a
        goal of relations seen to hold."""
        return self.abs.goal_holds(seen.reading, goal_atoms) and (
            not goal.relations or super().goal_seen(seen, goal_atoms, goal))


class _ContinuousModelMode(PlanningMode):
    """A mode that plans with the learned continuous model (abstraction/bilevel.py),
    `skeletons` first or not."""

    needs_refiner = True
    skeletons: ClassVar[bool]
    horizon: ClassVar[int | None] = None

    def __init__(self, abstraction: Abstraction, config: SolveConfig,
                 given: list[Action] | None = None):
        super().__init__(abstraction, config, given)
        from drake_symplan.abstraction.continuous import ContinuousModel
        from drake_symplan.abstraction.refiner import Refiner

        self.refiner = Refiner(abstraction.bundle.planning,
                               ContinuousModel(abstraction.bundle.continuous,
                                               radius=abstraction.bundle.relevance_radius))
        # costs added to the skeletons' moves, by their leading arguments (`observed`)
        self.penalties: Counter = Counter()

    def observed(self, step: PlanStep, predicted: Boxes | None, before: Observation,
                 seen: Observation) -> None:
        """What the arm missed costs more for the rest of the solve, so it does not try
        the same thing again while another way is left: a move of the continuous search
        whose boxes were seen off their predicted positions, in later searches
        (Refiner.missed); a skeleton's step whose outcome was not the predicted one (its
        positions, else its operator's symbols), its move with the same riders in later
        skeletons (bilevel.PENALTY). A step after which no box moved (a grasp that
        caught nothing) is missed whatever was predicted, in both: a skeleton run on its
        symbols alone predicts no positions, and its symbols can hold without a move."""
        from drake_symplan.abstraction.bilevel import PENALTY

        then, shifted = before.boxes.where(), moved(before, seen)
        self.refiner.refusals.keep({  # what was refused stands while nothing near it moved
            (side, box, offset) for side, box, offset in self.refiner.refusals.keys
            if box in then and not near_moved(box, then, shifted)})
        still = not shifted
        if isinstance(step, Step):
            if still or (off_prediction(predicted, seen) if predicted is not None
                         else self.abs.mismatches(seen.reading, step)):
                self.penalties[tuple(step.args)] += PENALTY
            if still:
                self.refiner.missed[step.action] += 1
        elif step.kind == "move" and (still or predicted is not None
                                      and off_prediction(predicted, seen)):
            self.refiner.missed[step.action] += 1

    def refused(self, step: PlanStep, obstacles: dict[str, np.ndarray] | None = None,
                at: str = "") -> None:
        """A step the arm could not run is missed, as one after which nothing moved, and
        its source at that grasp (refused `at` the release: its target at that release
        offset) is taken by no plan until a box within NEAR of it has moved; in the plans'
        predicted scenes, until one of the `obstacles` has moved (abstraction/refusals.py)."""
        from drake_symplan.abstraction.bilevel import PENALTY

        if isinstance(step, Step):
            self.penalties[tuple(step.args)] += PENALTY
        self.refiner.missed[step.action] += 1
        self.refiner.refusals.refuse(step.action, obstacles, at)

    def _plan(self, now: Observation, goal: Observation) -> Plan:
        from drake_symplan.abstraction.bilevel import Search, plan_bilevel

        return plan_bilevel(self.abs, self.refiner, now, goal, self.budget(),
                            Search(self.skeletons, self.config.planner,
                                   self.config.alternatives, self.horizon),
                            dict(self.penalties))

    def departs(self, step: PlanStep, predicted: Boxes | None, seen: Observation,
                rest: list[PlanStep], believed, goal_atoms, goal: Observation | None = None
                ) -> bool:
        """A plan checked in continuous space has left it when a box is off its predicted
        position and the rest of the plan, predicted again from what is seen, no longer
        reaches the goal (a small miss that the rest absorbs costs no replan); at its end
        the goal check decides. A skeleton run on its symbols: as a symbolic plan."""
        if not self.predicts_positions:
            return super().departs(step, predicted, seen, rest, believed, goal_atoms, goal)
        if predicted is None or not rest:
            return False
        off = off_prediction(predicted, seen)
        if not off or goal is None:
            return off
        end = self.refiner.rollout(seen.boxes, rest)
        return not self.refiner.reached(end, goal.boxes.where())


class BilevelMode(_ContinuousModelMode):
    name = "bilevel"
    help = ("symbolic skeletons checked and completed with the learned continuous model, "
            "a continuous search as the fallback")
    skeletons = True


class RecedingMode(_ContinuousModelMode):
    """Bilevel over a receding horizon."""

    name = "receding"
    help = ("bilevel over a receding horizon: a long skeleton's first step refined to its "
            "subgoal, then a new plan from what is seen")
    skeletons = True
    horizon = HORIZON
    # Not better than bilevel on the reproducible sets; its row would add
    # a fifth to the reproduction's time.
    reproduced = False

class ContinuousMode(_ContinuousModelMode):
    name = "continuous"
    help = "that search alone"
    skeletons = False


class OracleMode(PlanningMode):
    name = "oracle"
    help = "replay the actions that made the problem, open loop"
    needs_recorded_actions = True
    open_loop_only = True

    def _plan(self, now: Observation, goal: Observation) -> Plan:
        from drake_symplan.abstraction.abstraction import Plan

        if self.given is None:
            raise ValueError("the oracle replays a problem's recorded actions; none given")
        return Plan("solved", [Reposition(a, "move") for a in self.given], 0.0, "",
                    self.name, level=self.name)


PLANNING_MODES: dict[str, type[PlanningMode]] = {
    mode.name: mode for mode in (BilevelMode, RecedingMode, SymbolicMode, ContinuousMode,
                                 OracleMode)}


def mode_names(recorded_actions: bool = False) -> tuple[str, ...]:
    """The modes a command offers: those that replay recorded actions only where it has
    them (`recorded_actions`: eval planning, not solve)."""
    return tuple(name for name, mode in PLANNING_MODES.items()
                 if recorded_actions or not mode.needs_recorded_actions)


def make_planner(abstraction: Abstraction, config: SolveConfig,
                 given: list[Action] | None = None) -> PlanningMode:
    """The planning mode `config.planning` for one solve."""
    return PLANNING_MODES[config.planning](abstraction, config, given)
