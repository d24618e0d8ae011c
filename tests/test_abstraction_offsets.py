"""Choosing a step's offsets (abstraction/offsets.py) among its offset variants
(symbolic/structs.py's PlanningOperators): the geometric scorer lands the source nearer its
perceived goal, the learned model's scorer orders by the predicted distance to the goal,
and only operators after which the plan still reaches the goal's atoms are candidates."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from drake_symplan.abstraction.offsets import GeometricScorer, choose
from drake_symplan.actions import release_shift
from drake_symplan.symbolic.bundle import ModelBundle
from drake_symplan.symbolic.effect_operators import EFFECT
from drake_symplan.symbolic.structs import LiftedOperator, PlanningOperators, parse_step, reaches

FREE = (("p0", 0), ("p0", 1))  # both boxes have nothing on them


def op(index, release, add, pre=FREE, delete=(("p0", 1),), grasp="center"):
    return LiftedOperator(index, grasp, release, 2, pre, add, delete, 10, 10, 10)


ON = (("r0", 0, 1),)  # ?o0 rests on ?o1
OPERATORS = [op(0, "center", ON), op(1, "right", ON), op(2, "left", ON),
             op(3, "right", (("r1", 0, 1),)),  # lands right, but predicts another relation
             op(4, "right", ON, pre=(("p0", 0),)), op(5, "left", ON, grasp="right")]


def bundle():
    return ModelBundle(Path("oracle"), None, OPERATORS, EFFECT,
                       {"n_unary": 1, "n_relations": 2}, {})


STATE = {("p0", "a"), ("p0", "b")}
GOAL_ATOMS = {("r0", "a", "b")}
BY_NAME = {o.name: o for o in OPERATORS}


def step(text):
    return parse_step(text, BY_NAME)


STEP = step("(pick_center_place_center_n10_op0 a b)")


def positions(dy):
    """b at the origin, a resting on b shifted by dy along y."""
    return {"a": np.array([0.0, dy, 0.075]), "b": np.zeros(3)}


def test_offset_variants_apply_and_keep_the_goal_in_reach():
    variants = PlanningOperators(OPERATORS).variants
    names = [s.operator.name for s in variants(STEP, [], STATE, GOAL_ATOMS)]
    # op3 misses the goal's relation; op4 applies too (its one precondition holds).
    assert names == ["pick_center_place_center_n10_op0", "pick_center_place_right_n10_op1",
                     "pick_center_place_left_n10_op2", "pick_center_place_right_n10_op4",
                     "pick_right_place_left_n10_op5"]
    # A later step that needs b free rules out every one of them but the planned step.
    later = [step("(pick_center_place_center_n10_op0 b a)")]
    assert variants(STEP, later, STATE, set()) == [STEP]
    assert not reaches(later, {("p0", "a")}, set())


def geometric(now, goal, contacts):
    return choose(PlanningOperators(OPERATORS), STEP, [], STATE, GOAL_ATOMS,
                  GeometricScorer(now, goal, contacts))


def test_the_release_offset_follows_the_goal_position_on_the_target():
    now = {"a": np.array([0.3, 0.2, 0.025]), "b": np.zeros(3)}
    contact = {("a", "b")}
    assert str(geometric(now, positions(0.075), contact)) == \
        "(pick_center_place_right_n10_op1 a b)"
    # grasped 7.5 cm right of its centre and released at b's left: 15 cm to the left.
    assert str(geometric(now, positions(-0.15), contact)) == \
        "(pick_right_place_left_n10_op5 a b)"
    # Already where the planned step puts it (within MIN_GAIN): keep the plan's step.
    assert geometric(now, positions(0.005), contact) == STEP


def test_offsets_that_would_set_the_source_down_to_topple_are_passed_over():
    now = {"a": np.array([0.3, 0.2, 0.025]), "b": np.zeros(3)}
    goal = positions(-0.15)  # best: grasped right, released left (op5)

    def choose_safe(unsafe):
        return str(choose(PlanningOperators(OPERATORS), STEP, [], STATE, GOAL_ATOMS,
                          GeometricScorer(now, goal, {("a", "b")}), unsafe))

    assert choose_safe(lambda a: a.grasp == "right") == "(pick_center_place_left_n10_op2 a b)"
    # where every candidate is unsafe the best still runs (the monitor sees what comes)
    assert choose_safe(lambda a: True) == "(pick_right_place_left_n10_op5 a b)"


def test_without_goal_contact_the_absolute_goal_position_counts():
    now = {"a": np.array([0.3, 0.2, 0.025]), "b": np.array([0.0, -0.075, 0.025])}
    goal = {"a": np.array([0.0, 0.0, 0.3]), "b": np.array([0.5, 0.5, 0.025])}
    # b stands 7.5 cm left of a's goal now: release at b's right.
    assert str(geometric(now, goal, set())) == "(pick_center_place_right_n10_op1 a b)"


def test_the_predicted_scorer_orders_by_the_predicted_distance_to_the_goal(monkeypatch):
    from drake_symplan.abstraction.offsets import PredictedScorer, ranked

    class Shifted:  # "predicts" a's y: the release shift from b's centre
        positions = {"a": 0.0}

        def where(self):
            return {"a": np.array([0.0, self.positions["a"], 0.0])}

    def predict(_, steps):
        out = []
        for s in steps:
            after = Shifted()
            after.positions = {"a": release_shift(s.action)}
            out.append(after)
        return out

    def errors(boxes, goal):
        return {n: float(np.linalg.norm(p - goal[n])) for n, p in boxes.where().items()}

    monkeypatch.setattr("drake_symplan.abstraction.offsets.goal_errors", errors)
    order = ranked(PlanningOperators(OPERATORS), STEP, [], STATE, GOAL_ATOMS,
                   PredictedScorer(predict, None, {"a": np.array([0.0, -0.15, 0.0])}))
    # op5 lands a 15 cm left of b's centre, right on its goal; a tie keeps the order.
    assert [o.step.operator.index for o in order] == [5, 2, 0, 1, 4]
    assert order[0].predicted.positions == {"a": -0.15}


def test_the_planner_sees_one_operator_per_precondition_and_effect():
    shaky = LiftedOperator(6, "left", "left", 2, FREE, ON, (("p0", 1),), 10, 10, 2)
    planning = PlanningOperators([shaky, *OPERATORS])
    # op0-op2 and op5 equal the unreliable shaky one: the most reliable (op0) stands for
    # them; op3 (another effect) and op4 (other preconditions) stay.
    assert [op.index for op in planning.planned] == [0, 3, 4]
    assert [op.index for op in planning.operators[0].variants] == [6, 0, 1, 2, 5]
    assert "pick_left_place_left_n10_op6" not in bundle().domain
    assert bundle().domain.count("(:action") == 3


def test_of_the_moves_that_shift_a_source_alike_the_one_held_nearest_its_centre_is_kept():
    from drake_symplan.abstraction.offsets import central
    from drake_symplan.actions import Action
    from drake_symplan.symbolic.structs import Reposition

    moves = [Reposition(Action("l", g, t, r)) for t in ("c", "d")
             for g, r in (("left", "left"), ("center", "center"), ("right", "right"),
                          ("left", "center"), ("center", "right"), ("left", "right"))]
    kept = central(moves, lambda name: set())
    # per target: shift 0 (left-left, centre-centre, right-right), 7.5 cm (left-centre,
    # centre-right), 15 cm (left-right): centre-centre in left-left's place, centre-right
    assert [(m.action.grasp, m.action.release, m.action.target) for m in kept] == [
        ("center", "center", "c"), ("center", "right", "c"), ("left", "right", "c"),
        ("center", "center", "d"), ("center", "right", "d"), ("left", "right", "d")]
    # a block with a box on it keeps every grasp (its centre may be under the load)
    assert central(moves, lambda name: {"e"} if name == "l" else set()) == moves
