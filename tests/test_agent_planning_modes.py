"""The planning modes (agent/planning_modes.py): registry, monitor checks, what a mode learns."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from bilevel_fixtures import (
    STACK,
    START,
    TOWER,
    Lifting,
    Penalized,
    Skeletons,
    Stacking,
    boxes,
    solve,
)

from drake_symplan.abstraction.abstraction import Observation, Plan
from drake_symplan.abstraction.bilevel import PENALTY
from drake_symplan.abstraction.continuous import Boxes
from drake_symplan.abstraction.refiner import Refiner
from drake_symplan.actions import Action
from drake_symplan.agent.config import SolveConfig
from drake_symplan.agent.planning_modes import BilevelMode, PlanningMode, SymbolicMode
from drake_symplan.boxes import CONTACT_TOLERANCE
from drake_symplan.planning.budget import Budget
from drake_symplan.symbolic.structs import Reposition, Step


class Bundled(Skeletons):
    """Skeletons with the model bundle a continuous mode's constructor reads: the tiny
    domain's operators and an effect model (`bilevel_mode` plans with Stacking instead)."""

    bundle = SimpleNamespace(planning=list(STACK.values()), continuous=Lifting(),
                             relevance_radius=CONTACT_TOLERANCE)


def bilevel_mode(abstraction=None, **refiner_options) -> BilevelMode:
    """The default mode made by its constructor, its refiner on the hand-written model."""
    planner = BilevelMode(abstraction or Bundled(), SolveConfig())
    planner.refiner = Refiner(list(STACK.values()), Stacking(), **refiner_options)
    return planner


class Seen:
    """A perceived scene as the agent's monitor gets it (names, features(), contacts,
    objects with name and position), made from Boxes."""

    def __init__(self, scene: Boxes):
        self.names, self.contacts, self._features = scene.names, scene.contacts, scene.features
        self.objects = [SimpleNamespace(name=n, position=scene.features[i, :3].astype(float))
                        for i, n in enumerate(scene.names)]

    def features(self):
        return self._features


def test_a_miss_the_rest_of_the_plan_absorbs_costs_no_replan():
    planner = bilevel_mode()  # the monitor alone
    planner.last = Plan("solved", level="bilevel")
    tower = boxes(a=(0.7, 0.0, 0.075), b=(0.7, 0.0, 0.125), c=(0.7, 0.0, 0.025))
    steps = [Reposition(Action("a", "center", "c", "center"), "move"),
             Reposition(Action("b", "center", "a", "center"), "move")]
    predicted = Stacking().predict(START, [steps[0].action])[0]

    def seen(dx):
        where = predicted.positions.astype(float).copy()
        where[0, 0] += dx  # a landed dx off along x
        return Seen(predicted.moved(where))

    def departs(scene):
        return planner.departs(steps[0], predicted, observe(scene), steps[1:], None, None,
                               observe(Seen(tower)))

    assert not departs(seen(0.0))
    # 3.5 cm off: over the 3 cm deviation, but b follows a and both end within 4 cm.
    assert not departs(seen(0.035))
    assert departs(seen(0.06))  # 6 cm off: the rest cannot make up for it; replan
    assert not planner.departs(steps[1], predicted, observe(seen(0.06)), [], None, None,
                               observe(Seen(tower)))  # the last step: the goal check decides


def test_the_plans_end_is_checked_on_positions_unless_planning_is_symbolic():
    from drake_symplan.agent.planning_modes import PLANNING_MODES

    goal = boxes(a=(0.7, 0.0, 0.075), b=(0.7, 0.0, 0.025))
    off = boxes(a=(0.7, 0.08, 0.075), b=(0.7, 0.0, 0.025))  # a on b, 8 cm along it

    class AtomsHold(Bundled):
        def goal_holds(self, reading, atoms):
            return True  # the symbols say "a on b" for both scenes

    for planning, seen in (("symbolic", True), ("bilevel", False), ("continuous", False)):
        planner = PLANNING_MODES[planning](AtomsHold(), SolveConfig(planning=planning))
        planner.last = Plan("solved", level="symbolic")  # a skeleton run on its symbols
        assert planner.goal_seen(observe(Seen(off)), frozenset(), observe(Seen(goal))) is seen
        assert planner.goal_seen(observe(Seen(goal)), frozenset(), observe(Seen(goal)))


def observe(scene: Seen) -> Observation:
    """A perceived scene as the monitor gets it (no symbols read)."""
    return Observation(scene, None, Boxes.of(scene))


def test_each_mode_is_one_registered_class_whose_flags_say_what_it_needs():
    from drake_symplan.agent.planning_modes import PLANNING_MODES, mode_names

    assert tuple(PLANNING_MODES) == ("bilevel", "receding", "symbolic", "continuous",
                                     "oracle")
    assert all(issubclass(m, PlanningMode) and m.name == n for n, m in PLANNING_MODES.items())
    assert mode_names() == ("bilevel", "receding", "symbolic", "continuous")  # no actions
    assert mode_names(recorded_actions=True) == tuple(PLANNING_MODES)
    assert [n for n, m in PLANNING_MODES.items() if m.needs_refiner] == [
        "bilevel", "receding", "continuous"]
    assert [n for n, m in PLANNING_MODES.items() if m.open_loop_only] == ["oracle"]
    assert [n for n, m in PLANNING_MODES.items() if not m.reproduced] == ["receding"]
    assert SymbolicMode.needs_refiner is False
    try:
        SolveConfig(planning="nowhere")
    except ValueError as e:
        assert "bilevel" in str(e)
    else:
        raise AssertionError("an unknown mode passed")


def test_a_step_that_missed_its_prediction_makes_its_move_dearer_in_later_plans():
    planner = bilevel_mode()  # the monitor's side alone (the default mode)
    step = Step(STACK["center"], ("a", "c"))
    predicted = Stacking().predict(START, [step.action])[0]
    before = observe(Seen(START))
    planner.observed(step, predicted, before, observe(Seen(predicted)))  # as predicted
    assert not planner.penalties and not planner.refiner.missed
    short = boxes(a=(0.65, 0.05, 0.025), b=(0.5, -0.2, 0.025), c=(0.7, 0.0, 0.025))
    planner.observed(step, predicted, before, observe(Seen(short)))  # a fell short of c
    assert planner.penalties == {("a", "c"): PENALTY} and not planner.refiner.missed
    # The penalties reach every skeleton the symbolic planner is asked for.
    asked = Penalized()
    solve(asked, TOWER, horizon=1, penalties=dict(planner.penalties))
    assert asked.asked[0] == {("a", "c"): PENALTY}


class SymbolsHold(Bundled):
    """An abstraction whose symbols always come true (mismatches finds none)."""

    def mismatches(self, reading, step):
        return set()


def test_a_step_after_which_nothing_moved_is_missed_though_its_symbols_hold():
    planner = bilevel_mode(SymbolsHold())  # the monitor's side alone
    step = Step(STACK["center"], ("a", "c"))  # run on its symbols: no positions predicted
    before = observe(Seen(START))
    moved = boxes(a=(0.7, 0.0, 0.075), b=(0.5, -0.2, 0.025), c=(0.7, 0.0, 0.025))
    planner.observed(step, None, before, observe(Seen(moved)))
    assert not planner.penalties and not planner.refiner.missed
    nudged = boxes(a=(0.51, 0.2, 0.025), b=(0.5, -0.2, 0.025), c=(0.7, 0.0, 0.025))
    planner.observed(step, None, before, observe(Seen(nudged)))  # a grasp caught nothing
    assert planner.penalties == {("a", "c"): PENALTY}
    assert planner.refiner.missed == {step.action: 1}
    move = Reposition(Action("a", "center", "b", "center"), "move")
    planner.observed(move, None, before, observe(Seen(nudged)))
    assert planner.refiner.missed == {step.action: 1, move.action: 1}


def test_a_symbolic_plans_refusal_stands_until_a_box_near_its_source_moves():
    planner = SymbolicMode(SymbolsHold(), SolveConfig(planning="symbolic"))
    step = Step(STACK["center"], ("a", "c"))
    planner.refused(step)
    assert planner.refusals == {("a", "c"): PENALTY} and not planner.penalties
    before = observe(Seen(START))  # a at (0.5, 0.2), b at (0.5, -0.2), 40 cm from a
    b_moved = boxes(a=(0.5, 0.2, 0.025), b=(0.5, -0.3, 0.025), c=(0.7, 0.0, 0.025))
    other = Step(STACK["center"], ("b", "c"))
    planner.observed(other, None, before, observe(Seen(b_moved)))
    assert planner.refusals == {("a", "c"): PENALTY}  # b stood beyond NEAR of a
    c_moved = boxes(a=(0.5, 0.2, 0.025), b=(0.5, -0.2, 0.025), c=(0.7, 0.1, 0.025))
    planner.observed(other, None, before, observe(Seen(c_moved)))
    assert not planner.refusals and not planner.penalties  # c, 28 cm from a, moved


@pytest.mark.slow
def test_a_move_the_arm_missed_is_taken_another_way_in_later_searches():
    planner = bilevel_mode(defer=None)  # the monitor's side alone
    move = Reposition(Action("a", "center", "b", "center"), "move")
    predicted = Stacking().predict(START, [move.action])[0]
    before = observe(Seen(START))
    planner.observed(move, predicted, before, observe(Seen(predicted)))  # as predicted
    assert not planner.refiner.missed
    planner.observed(move, predicted, before, observe(Seen(START)))  # a never left
    assert planner.refiner.missed == {move.action: 1}
    # a on b, which stands beside c: onto b or onto c's right end, one step each
    side = boxes(a=(0.5, 0.2, 0.025), b=(0.7, 0.075, 0.025), c=(0.7, 0.0, 0.025))
    goal = {**side.where(), "a": np.array([0.7, 0.075, 0.075])}
    found, _ = planner.refiner.search(side, goal, Budget.of_cpu(10))
    assert [s.action for s in found.steps] == [Action("a", "center", "c", "right")]
    planner.refiner.missed.clear()
    found, _ = planner.refiner.search(side, goal, Budget.of_cpu(10))
    assert [s.action for s in found.steps] == [move.action]
    # Refused by the arm (a grasp under a stack): a at that grasp is in no plan while
    # nothing near a moves; once a box within NEAR of it has, it may be again.
    planner.refused(move)
    assert planner.refiner.refusals.keys == {("grasp", "a", "center")}
    found, _ = planner.refiner.search(side, goal, Budget.of_cpu(10))
    assert found is None  # every move of a grasps its centre
    far = boxes(a=(0.5, 0.2, 0.025), b=(0.5, -0.3, 0.025), c=(0.7, 0.0, 0.025))  # b, 40 cm
    planner.observed(move, predicted, before, observe(Seen(far)))
    assert planner.refiner.refusals.keys == {("grasp", "a", "center")}
    planner.observed(move, predicted, before, observe(Seen(predicted)))
    assert not planner.refiner.refusals.keys
