"""Outcomes the plan did not aim for. An action whose symbolic outcome branches: its operators (one per outcome, each with the
probability it followed in the data) make the planner aim through the likely outcome
(cost 1 + 10 -ln p, symbolic/structs.py), and the monitor replans when the other outcome
happens. The fake world of test_agent_loop: a centred place lands the box on the target
90 % of the time in the data, an off-centre one 30 %; here the first centred place misses.
And a box that rode on the carried one and was left behind counts as a dropped rider.
"""

from __future__ import annotations

import numpy as np
from test_agent_loop import FakeBackend, OracleAbstraction, OracleBundle, _on, cube, solve

from drake_symplan.actions import Action
from drake_symplan.agent.config import SolveConfig
from drake_symplan.agent.solve import Agent
from drake_symplan.robot.backends import Execution
from drake_symplan.symbolic.structs import LiftedOperator, PlanningOperators
from drake_symplan.world.scenes import Scene

FREE = (("free", 0), ("free", 1))


def _operators() -> list[LiftedOperator]:
    """Per action, the outcome 'on the target' and the outcome 'beside it' (nothing
    changes), with the counts of a data set: centre 90 of 100 on, left 30 of 100."""
    ops = []
    for offset, on in (("center", 90), ("left", 30)):
        for add, delete, n in (((("on", 0, 1),), (("free", 1),), on), ((), (), 100 - on)):
            ops.append(LiftedOperator(len(ops), offset, offset, 2, FREE, add, delete, 100,
                                      applicable=100, succeeded=n, outcomes=2,
                                      effect_count=n))
    return [op for op in ops if op.add]  # an outcome that changes nothing plans nothing


def _domain(operators, costs: bool) -> str:
    actions = []
    for op in operators:
        cost = f" (increase (total-cost) {op.cost})" if costs else ""
        actions.append(f" (:action {op.name} :parameters (?a ?b - obj)\n"
                       f"  :precondition (and (free ?a) (free ?b))\n"
                       f"  :effect (and (on ?a ?b) (not (free ?b)){cost}))")
    head = ("(define (domain symplan) (:requirements :strips :typing"
            + (" :action-costs)" if costs else ")") + " (:types obj)\n"
            " (:predicates (on ?x ?y - obj) (free ?x - obj) (different ?x ?y - obj))\n"
            + (" (:functions (total-cost) - number)\n" if costs else ""))
    return head + "\n".join(actions) + ")\n"


class TwoOutcomeBundle(OracleBundle):
    operators = _operators()
    planning = PlanningOperators(operators)
    planned, by_name = operators, {op.name: op for op in operators}
    domain, domain_strips = _domain(operators, True), _domain(operators, False)


class MissesOnce(FakeBackend):
    """The first place lands the box beside the target, on the table; then as planned."""

    def execute(self, action, before, lift=True):
        if self.executed:
            return super().execute(action, before, lift)
        self.executed.append(action)
        target = self.station.truth[action.target]
        self.station.truth[action.source] = np.array([target[0] + 0.1, target[1], 0.025])
        return Execution("ok", None, self.perceive(before))


def test_the_plan_goes_through_the_likely_outcome_and_replans_on_the_other():
    centre, left = TwoOutcomeBundle.operators
    assert (centre.reliability, left.reliability) == (0.9, 0.3)
    assert centre.cost < left.cost
    goal = Scene([cube("a", 0.8, 0.0, 0.075), cube("b", 0.8, 0.0), cube("c", 0.6, 0.25)])
    result, backend = solve(OracleAbstraction(bundle=TwoOutcomeBundle()), goal=goal, backend=MissesOnce())
    assert result.status == "success", result.to_json()
    assert result.replans == 1  # the other outcome happened: a is beside b, not on it
    assert [str(s) for s in result.executed] == [f"({centre.name} a b)"] * 2
    assert [(a.grasp, a.release) for a in backend.executed] == [("center", "center")] * 2


class CarriesRiders(FakeBackend):
    """As FakeBackend, and what rests on the source moves with it."""

    def execute(self, action, before, lift=True):
        truth = self.station.truth
        source = truth[action.source].copy()
        load = [n for n, p in truth.items() if n != action.source and _on(p, source)]
        out = super().execute(action, before, lift)
        for name in load:
            truth[name] = truth[name] - source + truth[action.source]
        return Execution(out.status, out.message, self.perceive(before))


def test_a_rider_left_behind_is_counted_as_dropped():
    start = Scene([cube("a", 0.6, -0.2), cube("c", 0.6, -0.2, 0.075), cube("b", 0.8, 0.0)])
    goal = Scene([cube("a", 0.8, 0.0, 0.075), cube("c", 0.8, 0.0, 0.125), cube("b", 0.8, 0.0)])
    config = SolveConfig("fd", 20.0, True, 0, refine=False, planning="oracle")
    given = [Action("a", "center", "b", "center")]
    dropped = Agent(FakeBackend()).solve(start, goal, OracleAbstraction(), config, given=given)
    assert dropped.dropped_riders == 1 and dropped.status == "failure"
    assert dropped.to_json()["dropped_riders"] == 1
    carried = Agent(CarriesRiders()).solve(start, goal, OracleAbstraction(), config,
                                           given=given)
    assert carried.dropped_riders == 0 and carried.status == "success", carried.to_json()
    assert "dropped_riders" not in carried.to_json()


class MissesThird(FakeBackend):
    """The third place lands the box on the table beside the target; the rest as planned."""

    def execute(self, action, before, lift=True):
        if len(self.executed) != 2:
            return super().execute(action, before, lift)
        self.executed.append(action)
        self.station.truth[action.source] = np.array([0.5, -0.3, 0.025])
        return Execution("ok", None, self.perceive(before))


def test_a_long_plan_whose_third_step_departs_replans_from_what_is_seen():
    start = Scene([cube("a", 0.6, -0.2), cube("b", 0.8, 0.0), cube("c", 0.6, 0.25),
                   cube("d", 0.5, 0.1)])
    tower = Scene([cube("a", 0.8, 0.0, 0.075), cube("b", 0.8, 0.0), cube("c", 0.8, 0.0, 0.125),
                   cube("d", 0.8, 0.0, 0.175)])
    result, backend = solve(OracleAbstraction(), start=start, goal=tower, backend=MissesThird())
    assert result.status == "success", result.to_json()
    steps = ["(pick_center_place_center_n1_op0 a b)", "(pick_center_place_center_n1_op0 c a)",
             "(pick_center_place_center_n1_op0 d c)"]
    assert [str(s) for s in result.plan] == steps  # bottom up: only a free box takes one
    # d landed on the table: the monitor saw it, and the plan from there is d on c again.
    assert result.replans == 1 and [str(s) for s in result.executed] == steps + steps[-1:]
    assert backend.station.truth["d"][2] == 0.175
