"""Repositioning (agent/reposition.py): a box the symbols leave off its goal spot on the
table is put down beside another box, a stack moves as one."""

from __future__ import annotations

import numpy as np

from drake_symplan.actions import Action
from drake_symplan.symbolic.structs import LiftedOperator, Reposition, parse_step

ON = LiftedOperator(0, "center", "center", 2, (("p0", 0), ("p0", 1)), (("r0", 0, 1),),
                    (("p0", 1),), 10, 10, 10)


def step(text):
    return parse_step(text, {ON.name: ON})


def scene(boxes, contacts=()):
    """A perceived scene of upright boxes: name -> (type, xyz)."""
    from drake_symplan.features import object_features
    from drake_symplan.perception.perceive import PerceivedObject, PerceivedScene

    return PerceivedScene([PerceivedObject(n, t, np.array(p, float), 0.0, 0.0,
                                           object_features(t, np.array(p, float), np.eye(3)),
                                           False, np.eye(3)) for n, (t, p) in boxes.items()],
                          set(contacts))


def cubes(**xy):
    return scene({n: ("cube", (x, y, 0.025)) for n, (x, y) in xy.items()})


def test_a_box_off_its_goal_on_the_table_is_put_down_beside_another():
    from drake_symplan.agent.reposition import reposition_step

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
    from drake_symplan.agent.reposition import reposition_step

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
    from drake_symplan.agent.reposition import carried, reposition_step

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


def test_no_repositioning_by_a_grasp_the_arm_refuses():
    from drake_symplan.agent.reposition import reposition_step

    def tower(y, levels):  # a tower of `levels` cubes at (0.6, y), t0 at the bottom
        return scene({**{f"t{i}": ("cube", (0.6, y, 0.025 + 0.05 * i)) for i in range(levels)},
                      "d": ("cube", (0.6, y - 0.15, 0.025))},
                     [(f"t{i}", f"t{i + 1}") for i in range(levels - 1)])

    # two on a box: the stack moves as one; three on it (under a stack of two): the arm
    # will not lift it (skills/carry.unpinchable), so no repositioning asks for it
    assert str(reposition_step([], tower(0.0, 2), tower(-0.075, 2), 0.05)) == \
        "(reposition_center_left t0 t1)"
    assert reposition_step([], tower(0.0, 3), tower(-0.075, 3), 0.05) is None


def test_a_free_box_in_the_arms_way_is_set_aside_as_far_as_there_is_from_the_step():
    from drake_symplan.agent.reposition import clearing_step

    now = cubes(a=(0.6, 0.0), b=(0.6, 0.07), c=(0.4, -0.3), d=(0.75, 0.3))
    refused = step("(pick_center_place_center_n10_op0 a c)")
    # b, beside a, is set down beside d (the only box that is neither a nor c), on d's
    # far side from a
    assert clearing_step(["b"], refused, now, set()) == \
        Reposition(Action("b", "center", "d", "right"))
    assert clearing_step(["b"], refused, now, {"b"}) is None  # part of a goal that holds
    assert clearing_step(["x"], refused, now, set()) is None  # not seen
    stacked = scene({"a": ("cube", (0.6, 0.0, 0.025)), "b": ("cube", (0.6, 0.07, 0.025)),
                     "e": ("cube", (0.6, 0.07, 0.075)), "c": ("cube", (0.4, -0.3, 0.025)),
                     "d": ("cube", (0.75, 0.3, 0.025))})
    assert clearing_step(["b", "e"], refused, stacked, set()) == \
        Reposition(Action("e", "center", "d", "right"))  # not b: it carries e


def test_the_later_step_moving_a_box_a_step_would_meet_runs_first_where_the_plan_allows():
    from drake_symplan.agent.reposition import unblocking

    state = frozenset({("p0", n) for n in "abcd"})
    first, later = step("(pick_center_place_center_n10_op0 a b)"), \
        step("(pick_center_place_center_n10_op0 c d)")
    goal = frozenset({("r0", "a", "b"), ("r0", "c", "d")})
    # a set on b would meet c, which the next step moves anyway: that one runs first
    assert unblocking(first, [later], state, goal, {"c"}) == 0
    # no later step moves d
    assert unblocking(first, [later], state, goal, {"d"}) is None
    # c set on a first takes a's top (p0 a), and a could no longer go on b
    onto_a = step("(pick_center_place_center_n10_op0 c a)")
    assert unblocking(first, [onto_a], state, frozenset({("r0", "a", "b"), ("r0", "c", "a")}),
                      {"c"}) is None


def test_no_later_step_runs_first_that_sets_its_box_on_one_the_plan_still_moves():
    from drake_symplan.agent.reposition import unblocking

    # a carry: the source need not be clear, so c set on a, then a (with c) on b, reaches
    # the goal in symbols; but a is still to move, and c would ride wherever a goes
    carry = LiftedOperator(1, "center", "center", 2, (("p0", 1),), (("r0", 0, 1),),
                           (("p0", 1),), 10, 10, 10)
    steps = {carry.name: carry}
    first = parse_step(f"({carry.name} a b)", steps)
    later = parse_step(f"({carry.name} c a)", steps)
    state = frozenset({("p0", n) for n in "abc"})
    goal = frozenset({("r0", "a", "b"), ("r0", "c", "a")})
    assert unblocking(first, [later], state, goal, {"c"}) is None
    # c on b, which no step before it moves: first
    onto_b = parse_step(f"({carry.name} c d)", steps)
    assert unblocking(first, [onto_b], state | {("p0", "d")}, frozenset(), {"c"}) == 0


def test_a_towers_base_moves_to_where_its_step_has_room():
    from drake_symplan.agent.reposition import room_step

    # b stands against c, which carries e: a cube set on b would rest against e. b is set
    # down 7.5 cm from c instead, where a on it meets no box: of such spots, the nearest
    boxes = {"a": ("cube", (0.4, -0.3, 0.025)), "b": ("cube", (0.6, 0.0, 0.025)),
             "c": ("cube", (0.6, 0.05, 0.025)), "e": ("cube", (0.6, 0.05, 0.075)),
             "d": ("cube", (0.75, 0.3, 0.025))}
    onto_b = step("(pick_center_place_center_n10_op0 a b)")
    assert room_step(onto_b, scene(boxes, [("c", "e")])) == \
        Reposition(Action("b", "center", "c", "left"))
    # with a box on b, b stays (its load is the tower's part)
    loaded = scene({**boxes, "f": ("cube", (0.6, 0.0, 0.075))}, [("c", "e"), ("b", "f")])
    assert room_step(onto_b, loaded) is None
    # a block set on a cube reaches 12.5 cm along y: beside any box, it rests on that one too
    block = scene({**boxes, "a": ("long", (0.4, -0.3, 0.025))}, [("c", "e")])
    assert room_step(onto_b, block) is None
