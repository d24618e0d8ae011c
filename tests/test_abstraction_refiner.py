"""The refiner (abstraction/refiner.py): skeletons refined, its search, the steps none may take."""

from __future__ import annotations

import numpy as np
import pytest
from bilevel_fixtures import STACK, START, TOWER, Skeletons, Stacking, boxes, solve

from drake_symplan.abstraction.abstraction import Plan
from drake_symplan.abstraction.continuous import Boxes
from drake_symplan.abstraction.refiner import Refiner, moves
from drake_symplan.abstraction.refusals import allows
from drake_symplan.actions import Action
from drake_symplan.features import object_features
from drake_symplan.planning.budget import Budget
from drake_symplan.planning.nodes import EXPANDED
from drake_symplan.symbolic.structs import Reposition, Step


def test_the_offsets_are_chosen_by_the_predicted_landing():
    goal = boxes(a=(0.7, 0.075, 0.075), b=(0.5, -0.2, 0.025), c=(0.7, 0.0, 0.025))
    skeleton = Plan("solved", [Step(STACK["center"], ("a", "c"))])  # lands 7.5 cm short
    found = solve(Skeletons(skeleton), goal)
    assert found.solved and [s.operator.release for s in found.steps] == ["right"]


def test_extra_moves_put_a_box_at_its_goal_spot_the_symbols_do_not_name():
    goal = boxes(a=(0.5, 0.2, 0.025), b=(0.7, 0.075, 0.075), c=(0.7, 0.0, 0.025))
    found = solve(Skeletons(Plan("solved", [])), goal, extra_moves=1)  # symbols hold already
    assert found.solved and found.steps == [
        Reposition(Action("b", "center", "c", "right"), "reposition")]


def test_the_search_predicts_the_moves_the_goals_order_asks_for_first():
    tower = boxes(a=(0.7, 0.0, 0.125), b=(0.7, 0.0, 0.075), c=(0.7, 0.0, 0.025))
    goal = tower.where()
    asked = Refiner(list(STACK.values()), Stacking())
    before = EXPANDED.total
    found, _ = asked.search(START, goal, Budget.of_cpu(10))
    assert EXPANDED.total - before == 2  # search nodes: the start, b on c
    # b onto c (c is in place), then a onto b: three releases each, the cubes' one grasp
    assert [s.action for s in found.steps] == [Action("b", "center", "c", "center"),
                                               Action("a", "center", "b", "center")]
    assert asked.predictions == 3 + 3
    every = Refiner(list(STACK.values()), Stacking(), defer=None)
    again, _ = every.search(START, goal, Budget.of_cpu(10))
    # every move of every box: 3 x 2 targets x 3 releases at the start, 9 with b on c
    assert again.steps == found.steps and every.predictions == 18 + 9


def test_a_box_is_placed_only_on_a_box_with_nothing_on_it_and_not_on_what_it_carries():
    scene = boxes(a=(0.5, 0.0, 0.025), b=(0.5, 0.01, 0.075), c=(0.5, 0.0, 0.125),
                  d=(0.7, 0.0, 0.025))
    assert scene.riding("a") == {"b", "c"} and scene.riding("b") == {"c"}
    assert scene.riding("c") == scene.riding("d") == set()

    def targets(source, riding=scene.riding):
        return {m.action.target for m in moves(scene.names, {source}, scene.half_length,
                                               "move", riding)}

    assert targets("a") == {"d"}  # not b or c, which ride on it
    assert targets("d") == {"c"}  # the tower's top, not a or b under it
    assert targets("a", None) == {"b", "c", "d"}
    # a block on a cube whose end reaches over another cube beside it (its centre is not
    # over that cube, so nothing rides on it): that cube is covered all the same
    features = np.stack([object_features("cube", np.array([0.7, 0.0, 0.025]), np.eye(3)),
                         object_features("long", np.array([0.7, 0.0, 0.075]), np.eye(3)),
                         object_features("cube", np.array([0.7, 0.11, 0.025]), np.eye(3)),
                         object_features("cube", np.array([0.5, 0.3, 0.025]), np.eye(3))])
    over = Boxes(("a", "l", "e", "f"), features, frozenset()).moved(features[:, :3])
    assert over.riding("e") == set() and over.covered() == {"a", "e"}
    assert {m.action.target for m in moves(over.names, {"f"}, over.half_length, "move",
                                           over.riding, over.covered())} == {"l"}


def test_no_plan_lifts_a_cube_from_under_a_stack_of_two_as_the_arm_would_not():
    # the skill's rule (skills/carry.unpinchable) on the believed boxes: the arm refuses
    # such a grasp, so the planner plans none; one rider, or a block with its end clear, it
    # lifts
    tower = boxes(a=(0.5, 0.0, 0.025), b=(0.5, 0.0, 0.075), c=(0.5, 0.0, 0.125),
                  d=(0.7, 0.2, 0.025))
    refiner = Refiner(list(STACK.values()), Stacking())
    assert refiner.refusals.barred(tower) == {("grasp", "a", "center")}
    goal = {**tower.where(), "a": np.array([0.7, 0.2, 0.075])}  # the base onto d
    found, _ = refiner.search(tower, goal, Budget.of_cpu(10))
    sources = [s.action.source for s in found.steps]
    assert sources[0] == "c" and "a" in sources  # the top off first (else: a alone)
    two = boxes(a=(0.5, 0.0, 0.025), b=(0.5, 0.0, 0.075), d=(0.7, 0.2, 0.025))
    assert refiner.refusals.barred(two) == set()
    block = np.stack([object_features("long", np.array([0.5, 0.0, 0.025]), np.eye(3)),
                      *[object_features("cube", np.array([0.5, 0.1, z]), np.eye(3))
                        for z in (0.075, 0.125)]])
    on_its_end = Boxes(("l", "b", "c"), block, frozenset()).moved(block[:, :3])
    assert on_its_end.riding("l") == {"b", "c"}
    assert refiner.refusals.barred(on_its_end) == set()  # the fingers close at the clear end
    refiner.refusals.refuse(Action("d", "center", "a", "center"))
    assert refiner.refusals.barred(tower) == {("grasp", "a", "center"), ("grasp", "d", "center")}
    # the arm's rules asked of some sources only (the search asks those it predicts): the
    # refusals of this solve stand whatever is asked
    assert refiner.refusals.barred(tower, {"b"}) == {("grasp", "d", "center")}
    assert refiner.refusals.barred(tower, {"a"}) == {("grasp", "a", "center"), ("grasp", "d", "center")}


def test_no_plan_grasps_a_cube_under_the_end_of_a_block_as_the_palm_would_strike_it():
    # traced (eight boxes): a block on two cubes, its end over a third cube (c) it does not
    # touch; the palm coming down to c struck the block and a tower of three fell. The
    # planner reads the skill's rule (skills/geometry.grasp_struck) and moves the block off
    # first; the cube under the block's centre (a) carries it as a rider.
    features = np.stack([object_features("cube", np.array([0.816, y, 0.025]), np.eye(3))
                         for y in (0.036, 0.111, 0.182)]
                        + [object_features("long", np.array([0.814, 0.111, 0.075]), np.eye(3)),
                           object_features("cube", np.array([0.6, -0.2, 0.025]), np.eye(3))])
    bridge = Boxes(("c", "a", "e", "l", "d"), features, frozenset()).moved(features[:, :3])
    refiner = Refiner(list(STACK.values()), Stacking())
    assert refiner.refusals.barred(bridge) == {("grasp", "c", "center"), ("grasp", "e", "center")}
    goal = {**bridge.where(), "c": np.array([0.6, -0.2, 0.075])}  # c onto d
    found, _ = refiner.search(bridge, goal, Budget.of_cpu(10))
    sources = [s.action.source for s in found.steps]
    assert sources[0] == "l" and sources.count("c") == 1  # the block off c, and back


def test_the_boxes_crowding_a_box_the_order_asks_to_move_are_asked_off_first():
    # as o16/p018 of relations30: a cube to move (c, onto d) under a block's end (l) that
    # the goal leaves free; the arm's rules bar every grasp of c while l stands there, so
    # the order asks for l's moves first (Refusals.crowding) rather than every box's at once
    features = np.stack([object_features("cube", np.array([0.816, y, 0.025]), np.eye(3))
                         for y in (0.036, 0.111, 0.182)]
                        + [object_features("long", np.array([0.814, 0.111, 0.075]), np.eye(3))]
                        + [object_features("cube", np.array(p), np.eye(3))
                           for p in ((0.6, -0.2, 0.025), (0.5, 0.25, 0.025))])
    bridge = Boxes(("c", "a", "e", "l", "d", "f"), features, frozenset()).moved(features[:, :3])
    refiner = Refiner(list(STACK.values()), Stacking())
    assert refiner.refusals.crowding(bridge, {"c"}) == {"l"}
    goal = {n: p for n, p in bridge.where().items() if n in "aed"}
    goal["c"] = np.array([0.6, -0.2, 0.075])
    found, _ = refiner.search(bridge, goal, Budget.of_cpu(10))
    assert [str(s.action) for s in found.steps] == ["pick(l:center) place(f:center)",
                                                    "pick(c:center) place(d:center)"]
    assert refiner.predictions == 93  # 111 with every move predicted at the start


def test_no_step_sets_a_block_down_into_a_taller_tower_beside_its_target():
    # traced (eight boxes): a block (25 cm along y) centred on a cube 7 cm from a tower of
    # three was lowered into the tower, which fell; the arm refuses it and the planner
    # takes no such step (skills/geometry.set_down_struck)
    where = {**{f"t{i}": ("cube", (0.83, 0.127, 0.025 + 0.05 * i)) for i in range(3)},
             "c": ("cube", (0.829, 0.197, 0.025)), "b": ("long", (0.938, 0.044, 0.025)),
             "d": ("cube", (0.6, 0.07, 0.025))}
    features = np.stack([object_features(kind, np.array(p), np.eye(3))
                         for kind, p in where.values()])
    scene = Boxes(tuple(where), features, frozenset()).moved(features[:, :3])
    refiner = Refiner(list(STACK.values()), Stacking())
    after = Stacking().predict(scene, [Action("b", "center", "c", "center")])[0]
    assert refiner.unsafe(scene, after, Action("b", "center", "c", "center"))
    assert not refiner.topples(scene, after)  # not by statics: by the arm
    for clear in (Action("b", "center", "d", "center"), Action("d", "center", "c", "center"),
                  Action("b", "center", "t2", "center")):
        assert not refiner.refusals.release_refused(scene, clear)


def test_no_step_sets_a_load_down_whose_rider_comes_down_into_a_tower():
    # traced (eight boxes): pick(o5:center) place(o4:right), a cube carrying a block (25 cm
    # along y) lowered beside a tower of four, brought the block's end down into the tower,
    # which fell. The cube's own footprint is clear; the rider's is not. The arm refuses
    # it, and the planner takes no such step.
    where = {**{f"t{i}": ("cube", (0.736, 0.151, 0.025 + 0.05 * i)) for i in range(4)},
             "b": ("cube", (0.946, 0.332, 0.025)), "c": ("cube", (0.946, 0.332, 0.075)),
             "l": ("long", (0.946, 0.332, 0.125)), "d": ("cube", (0.6, -0.2, 0.025))}
    features = np.stack([object_features(kind, np.array(p), np.eye(3))
                         for kind, p in where.values()])
    scene = Boxes(tuple(where), features, frozenset()).moved(features[:, :3])
    refusals = Refiner(list(STACK.values()), Stacking()).refusals
    assert refusals.release_refused(scene, Action("c", "center", "t3", "right"))
    assert refusals.release_refused(scene, Action("c", "center", "t3", "left"))
    for clear in (Action("c", "center", "t3", "center"),  # on the tower's top
                  Action("c", "center", "d", "right"),  # beside a lone cube
                  Action("l", "center", "t3", "right")):  # the block alone, 7.5 cm beside
        assert not refusals.release_refused(scene, clear), clear


def test_no_step_sets_a_box_down_where_the_cameras_lose_it():
    # perception keeps y within +-0.56 m: a cube set 7.5 cm right of a cube at y = 0.50
    # lands at 0.575, out of view (a row run off it lost its last box and every name
    # after); set left of it (0.425) it stays in view, and so does one set right of a cube
    # at 0.46 (0.535: seen 0.3 cm off). A block centred on a cube at 0.55 is past the
    # margin, on one at 0.54 not (its ends past the crop, its middle seen).
    where = {"t": ("cube", (0.7, 0.50, 0.025)), "u": ("cube", (0.6, 0.54, 0.025)),
             "v": ("cube", (0.8, 0.46, 0.025)), "w": ("cube", (0.9, 0.55, 0.025)),
             "c": ("cube", (0.7, -0.1, 0.025)), "b": ("long", (0.6, -0.2, 0.025))}
    features = np.stack([object_features(kind, np.array(p), np.eye(3))
                         for kind, p in where.values()])
    scene = Boxes(tuple(where), features, frozenset()).moved(features[:, :3])
    refusals = Refiner(list(STACK.values()), Stacking()).refusals
    assert refusals.release_refused(scene, Action("c", "center", "t", "right"))
    assert not refusals.release_refused(scene, Action("c", "center", "t", "left"))
    assert not refusals.release_refused(scene, Action("c", "center", "v", "right"))
    assert refusals.release_refused(scene, Action("b", "center", "w", "center"))
    assert not refusals.release_refused(scene, Action("b", "center", "u", "center"))


@pytest.mark.slow
def test_a_grasp_refused_for_a_box_in_the_way_is_planned_once_that_box_is_moved():
    # the arm refused a at its centre: its wrist would strike d. In the plans' predicted
    # scenes the refusal stands while d stays where it was seen, so d goes first
    scene = boxes(a=(0.5, 0.2, 0.025), b=(0.7, 0.075, 0.025), d=(0.5, 0.3, 0.025),
                  e=(0.8, -0.2, 0.025))
    goal = {n: p for n, p in scene.where().items() if n != "d"}  # d may go anywhere
    goal["a"] = np.array([0.7, 0.075, 0.075])
    refiner = Refiner(list(STACK.values()), Stacking())
    refiner.refusals.refuse(Action("a", "center", "b", "center"), {"d": scene.where()["d"]})
    assert refiner.refusals.barred(scene) == {("grasp", "a", "center")}
    assert refiner.refusals.in_the_way(scene) == {"d"}
    found, _ = refiner.search(scene, goal, Budget.of_cpu(10))
    assert [s.action.source for s in found.steps] == ["d", "a"]
    assert refiner.refusals.in_the_way(found.predicted[0]) == set()
    # with d's place in the goal too and one step allowed, nothing reaches the goal nor
    # comes nearer it: the step that moves d is what the search hands back to run
    stay = {**goal, "d": scene.where()["d"]}
    found, nearest = refiner.search(scene, stay, Budget.of_cpu(10), max_depth=1)
    assert found is None and [s.action.source for s in nearest.steps] == ["d"]
    assert refiner.clears_way(scene, nearest)
    refiner.refusals.blockers.clear()  # refused with no box known in the way: a stays
    found, _ = refiner.search(scene, goal, Budget.of_cpu(10))
    assert found is None
    # refused at the release (the wrist would strike a box beside b): nothing is set down
    # on b at that offset, from any source, and a may go elsewhere
    refiner = Refiner(list(STACK.values()), Stacking())
    refiner.refusals.refuse(Action("a", "center", "b", "center"), at="release")
    assert refiner.refusals.barred(scene) == {("release", "b", "center")}
    assert not allows(Action("e", "center", "b", "center"), refiner.refusals.barred(scene))
    assert allows(Action("a", "center", "b", "left"), refiner.refusals.barred(scene))
    assert allows(Action("a", "center", "e", "center"), refiner.refusals.barred(scene))


def test_a_subgoal_holds_the_boxes_the_rest_leaves_alone_to_their_goals():
    refiner = Refiner(list(STACK.values()), Stacking())
    goal = TOWER.where()
    before = {"a": 0.3, "b": 0.3, "c": 0.0}
    at_goal = TOWER
    assert refiner.subgoal_reached(at_goal, goal, before, placed={"a"}, later={"b"})
    b_away = boxes(a=(0.7, 0.0, 0.075), b=(0.5, -0.2, 0.025), c=(0.7, 0.0, 0.025))
    # b is 0.3 m off its goal and left alone: it may stay so, but not be placed off it...
    assert refiner.subgoal_reached(b_away, goal, before, placed={"a"}, later=set())
    assert not refiner.subgoal_reached(b_away, goal, before, placed={"a", "b"}, later=set())
    # ... nor be pushed farther from it; and c, at its goal before, must stay there.
    assert not refiner.subgoal_reached(b_away, goal, {**before, "b": 0.25}, {"a"}, set())
    c_moved = boxes(a=(0.7, 0.0, 0.075), b=(0.7, 0.0, 0.125), c=(0.6, 0.0, 0.025))
    assert not refiner.subgoal_reached(c_moved, goal, before, {"a"}, later={"b"})
    assert refiner.subgoal_reached(c_moved, goal, before, {"a"}, later={"b", "c"})
