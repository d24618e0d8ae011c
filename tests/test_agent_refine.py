"""Choosing a step's offsets among interchangeable operators (agent/refine.py): the source
lands nearer its perceived goal, and only operators after which the plan still reaches the
goal's atoms are candidates."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from drake_symplan.abstraction.bilevel import equivalents
from drake_symplan.actions import Action
from drake_symplan.agent.refine import refine_step
from drake_symplan.symbolic.bundle import ModelBundle
from drake_symplan.symbolic.effect_operators import EFFECT
from drake_symplan.symbolic.structs import LiftedOperator, Reposition, parse_step, reaches

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


def test_interchangeable_operators_apply_and_keep_the_goal_in_reach():
    names = [s.operator.name for s in equivalents(OPERATORS, STEP, [], STATE, GOAL_ATOMS)]
    # op3 misses the goal's relation; op4 applies too (its one precondition holds).
    assert names == ["pick_center_place_center_n10_op0", "pick_center_place_right_n10_op1",
                     "pick_center_place_left_n10_op2", "pick_center_place_right_n10_op4",
                     "pick_right_place_left_n10_op5"]
    # A later step that needs b free rules out every one of them but the planned step.
    later = [step("(pick_center_place_center_n10_op0 b a)")]
    assert equivalents(OPERATORS, STEP, later, STATE, set()) == [STEP]
    assert not reaches(later, {("p0", "a")}, set())


def test_the_release_offset_follows_the_goal_position_on_the_target():
    b = OPERATORS
    now = {"a": np.array([0.3, 0.2, 0.025]), "b": np.zeros(3)}
    contact = {("a", "b")}
    right = refine_step(b, STEP, [], STATE, GOAL_ATOMS, now, positions(0.075), contact)
    assert str(right) == "(pick_center_place_right_n10_op1 a b)"
    # grasped 7.5 cm right of its centre and released at b's left: 15 cm to the left.
    left = refine_step(b, STEP, [], STATE, GOAL_ATOMS, now, positions(-0.15), contact)
    assert str(left) == "(pick_right_place_left_n10_op5 a b)"
    # Already where the planned step puts it (within MIN_GAIN): keep the plan's step.
    assert refine_step(b, STEP, [], STATE, GOAL_ATOMS, now, positions(0.005), contact) == STEP


def test_without_goal_contact_the_absolute_goal_position_counts():
    now = {"a": np.array([0.3, 0.2, 0.025]), "b": np.array([0.0, -0.075, 0.025])}
    goal = {"a": np.array([0.0, 0.0, 0.3]), "b": np.array([0.5, 0.5, 0.025])}
    # b stands 7.5 cm left of a's goal now: release at b's right.
    assert str(refine_step(OPERATORS, STEP, [], STATE, GOAL_ATOMS, now, goal, set())) == \
        "(pick_center_place_right_n10_op1 a b)"


def test_the_planner_sees_one_operator_per_precondition_and_effect():
    from drake_symplan.symbolic.bundle import planning_operators

    shaky = LiftedOperator(6, "left", "left", 2, FREE, ON, (("p0", 1),), 10, 10, 2)
    kept = planning_operators([shaky, *OPERATORS])
    # op0-op2 and op5 equal the unreliable shaky one: the most reliable (op0) stands for
    # them; op3 (another effect) and op4 (other preconditions) stay.
    assert [op.index for op in kept] == [0, 3, 4]
    assert "pick_left_place_left_n10_op6" not in bundle().domain
    assert bundle().domain.count("(:action") == 3


def scene(boxes, contacts=()):
    """A perceived scene of upright boxes: name -> (type, xyz)."""
    from drake_symplan.perception.perceive import PerceivedObject, PerceivedScene

    return PerceivedScene([PerceivedObject(n, t, np.array(p, float), 0.0, 0.0, np.zeros(9),
                                           False, np.eye(3)) for n, (t, p) in boxes.items()],
                          set(contacts))


def cubes(**xy):
    return scene({n: ("cube", (x, y, 0.025)) for n, (x, y) in xy.items()})


def test_a_box_off_its_goal_on_the_table_is_put_down_beside_another():
    from drake_symplan.agent.refine import reposition_step

    now = cubes(a=(0.5, 0.3), b=(0.6, 0.0), c=(0.4, -0.2))
    goal = cubes(a=(0.6, 0.08), b=(0.6, 0.0), c=(0.4, -0.2))
    # a's goal is 8 cm to b's right: a cube is grasped at its centre, released at b's right.
    move = reposition_step([], now, goal, 0.05)
    assert move == Reposition(Action("a", "center", "b", "right"))
    assert str(move) == "(reposition_center_right a b)"
    # Within the tolerance already: nothing to do.
    assert reposition_step([], goal, goal, 0.05) is None
    # A later step moves a: that step decides where it goes.
    assert reposition_step([step("(pick_center_place_center_n10_op0 a c)")], now, goal,
                           0.05) is None
    # No box offers a landing within LAND_TOLERANCE of the goal.
    far = cubes(a=(0.6, 0.2), b=(0.6, 0.0), c=(0.4, -0.2))
    assert reposition_step([], now, far, 0.05) is None


def test_no_repositioning_onto_an_occupied_spot_of_a_box_that_carries_or_is_carried():
    from drake_symplan.agent.refine import reposition_step

    goal = cubes(a=(0.6, 0.08), b=(0.6, 0.0), c=(0.4, -0.2))
    taken = cubes(a=(0.5, 0.3), b=(0.6, 0.0), c=(0.6, 0.1))  # c stands where a would land
    assert reposition_step([], taken, goal, 0.05) is None
    carrying = scene({"a": ("cube", (0.5, 0.3, 0.025)), "b": ("cube", (0.6, 0.0, 0.025)),
                      "c": ("cube", (0.5, 0.3, 0.075))}, [("a", "c")])
    goal_c = cubes(a=(0.6, 0.08), b=(0.6, 0.0), c=(0.5, 0.3))
    assert reposition_step([], carrying, goal_c, 0.05) is None  # c would fall off a
    # In the goal a rests on b: the plan's step onto b places it, not a repositioning.
    on_b = scene({"a": ("cube", (0.6, 0.0, 0.075)), "b": ("cube", (0.6, 0.0, 0.025)),
                  "c": ("cube", (0.4, -0.2, 0.025))}, [("a", "b")])
    assert reposition_step([], cubes(a=(0.5, 0.3), b=(0.6, 0.0), c=(0.4, -0.2)), on_b,
                           0.05) is None


def test_a_stack_in_the_wrong_place_moves_as_one():
    from drake_symplan.agent.refine import carried, reposition_step

    def stack(y):  # a rests on b at (0.6, y)
        return scene({"a": ("cube", (0.6, y, 0.075)), "b": ("cube", (0.6, y, 0.025))},
                     [("a", "b")])

    assert carried(stack(0.0), "b") == {"a"} and carried(stack(0.0), "a") == set()
    # The goal has the stack 7.5 cm to the left: pick b (a rides along), release at a's
    # left, a's position taken before the move.
    assert str(reposition_step([], stack(0.0), stack(-0.075), 0.05)) == \
        "(reposition_center_left b a)"
    # A later step moves a: b alone is off by 7.5 cm and goes all the same.
    assert str(reposition_step([step("(pick_center_place_center_n10_op0 a b)")], stack(0.0),
                               stack(-0.075), 0.05)) == "(reposition_center_left b a)"
