"""Bilevel planning (abstraction/bilevel.py) on a tiny domain with a hand-written continuous
model: skeletons checked against the goal positions, offsets chosen by prediction, the
continuous search where the symbols find nothing; the continuous model's arithmetic."""

from __future__ import annotations

import time
from collections import Counter
from types import SimpleNamespace

import numpy as np
import pytest
import torch

from drake_symplan.abstraction import bilevel
from drake_symplan.abstraction.abstraction import Observation, Plan
from drake_symplan.abstraction.bilevel import PENALTY, Search, plan_bilevel
from drake_symplan.abstraction.continuous import Boxes, ContinuousModel
from drake_symplan.abstraction.refiner import Refiner, moves, set_down_tips
from drake_symplan.abstraction.refusals import allows
from drake_symplan.abstraction.stability import on_overhang, overloaded, tips, unstable
from drake_symplan.actions import Action, release_shift
from drake_symplan.agent.planning_modes import (
    BilevelMode,
    PlanningMode,
    SymbolicMode,
)
from drake_symplan.features import object_features
from drake_symplan.planning.budget import Budget
from drake_symplan.symbolic.structs import LiftedOperator, Reposition, Step

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

    def plan(self, start, goal, planner, budget, focus=True, penalties=None):
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


def test_a_skeleton_whose_predicted_end_misses_the_goal_is_rejected_for_one_that_meets_it():
    goal = boxes(a=(0.7, 0.0, 0.075), b=(0.5, -0.2, 0.025), c=(0.7, 0.0, 0.025))
    on_b = Plan("solved", [Step(STACK["center"], ("a", "b"))])
    on_c = Plan("solved", [Step(STACK["center"], ("a", "c"))])
    found = solve(Skeletons(on_b, on_c), goal)
    assert found.solved and found.level == "bilevel"
    assert [str(s) for s in found.steps] == [str(Step(STACK["center"], ("a", "c")))]
    first, second = found.candidates
    assert not first.accepted and "predicted off the goal" in first.why and "'a'" in first.why
    assert first.errors_cm["a"] > 20 and second.accepted and second.errors_cm["a"] == 0.0
    assert np.allclose(found.predicted[-1].where()["a"], [0.7, 0.0, 0.075])


class Penalized(Skeletons):
    """A symbolic planner that puts a on b unless that move is made dearer, then a on c."""

    def __init__(self):
        super().__init__()
        self.asked = []

    def plan(self, start, goal, planner, budget, focus=True, penalties=None):
        self.asked.append(dict(penalties or {}))
        target = "c" if ("a", "b") in (penalties or {}) else "b"
        return Plan("solved", [Step(STACK["center"], ("a", target))])


def test_an_alternative_skeleton_avoids_the_moves_of_one_that_did_not_refine():
    goal = boxes(a=(0.7, 0.0, 0.075), b=(0.5, -0.2, 0.025), c=(0.7, 0.0, 0.025))
    planner = Penalized()
    found = solve(planner, goal, alternatives=2)
    assert found.solved and found.level == "bilevel"
    assert [str(s) for s in found.steps] == [str(Step(STACK["center"], ("a", "c")))]
    # The focus plan, the plan over every object (the same: no candidate), then one
    # with the rejected move a -> b made dearer.
    assert planner.asked == [{}, {}, {("a", "b"): PENALTY}]
    assert [(c.source, c.accepted) for c in found.candidates] == [("skeleton 1", False),
                                                                  ("skeleton 2", True)]
    # Without alternatives the continuous search finds that move instead.
    found = solve(Penalized(), goal)
    assert found.level == "continuous" and [s.action for s in found.steps] == [
        Action("a", "center", "c", "center")]


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


def test_the_continuous_fallback_finds_a_two_step_plan_the_symbols_cannot():
    tower = boxes(a=(0.7, 0.0, 0.125), b=(0.7, 0.0, 0.075), c=(0.7, 0.0, 0.025))
    found = solve(Skeletons(Plan("unsolvable"), Plan("unsolvable")), tower)
    assert found.solved and found.level == "continuous"
    assert [s.action for s in found.steps] == [Action("b", "center", "c", "center"),
                                               Action("a", "center", "b", "center")]
    assert all(isinstance(s, Reposition) and s.kind == "move" for s in found.steps)
    assert [c.source for c in found.candidates] == ["skeleton 1", "skeleton 2", "continuous"]
    assert solve(Skeletons(), tower, skeletons=False).steps == found.steps


def test_the_search_predicts_the_moves_the_goals_order_asks_for_first():
    tower = boxes(a=(0.7, 0.0, 0.125), b=(0.7, 0.0, 0.075), c=(0.7, 0.0, 0.025))
    goal = tower.where()
    asked = Refiner(list(STACK.values()), Stacking())
    found, _ = asked.search(START, goal, Budget.of_cpu(10))
    # b onto c (c is in place), then a onto b: three releases each, the cubes' one grasp
    assert [s.action for s in found.steps] == [Action("b", "center", "c", "center"),
                                               Action("a", "center", "b", "center")]
    assert asked.predictions == 3 + 3
    every = Refiner(list(STACK.values()), Stacking(), defer=None)
    again, _ = every.search(START, goal, Budget.of_cpu(10))
    # every move of every box: 3 x 2 targets x 3 releases at the start, 9 with b on c
    assert again.steps == found.steps and every.predictions == 18 + 9


def test_a_skeleton_longer_than_the_boxes_off_their_goal_gives_way_to_a_shorter_search():
    goal = boxes(a=(0.7, 0.0, 0.075), b=(0.5, -0.2, 0.025), c=(0.7, 0.0, 0.025))
    detour = Plan("solved", [Step(STACK["center"], ("a", "b")), Step(STACK["center"], ("a", "c"))])
    found = solve(Skeletons(detour), goal)  # one box off its goal, a skeleton of two steps
    assert found.solved and found.level == "continuous"
    assert [s.action for s in found.steps] == [Action("a", "center", "c", "center")]
    skeleton, search = found.candidates
    assert skeleton.accepted and len(skeleton.steps) == 2
    assert search.accepted and search.why == "1 step where the refined skeleton takes 2"


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
    # planner reads the skill's rule (skills/geometry.palm_struck) and moves the block off
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
        assert not refiner.refusals.sets_down_into(scene, clear)


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
    assert refusals.sets_down_into(scene, Action("c", "center", "t3", "right"))
    assert refusals.sets_down_into(scene, Action("c", "center", "t3", "left"))
    for clear in (Action("c", "center", "t3", "center"),  # on the tower's top
                  Action("c", "center", "d", "right"),  # beside a lone cube
                  Action("l", "center", "t3", "right")):  # the block alone, 7.5 cm beside
        assert not refusals.sets_down_into(scene, clear), clear


def test_a_block_grasped_at_its_end_and_released_over_a_cube_would_topple():
    # traced (eight boxes): pick(o3:right) place(o6:center) brought the block's centre down
    # 7.5 cm off a cube atop a tower, and block and tower fell; the model predicted the
    # block resting on the cube. The action's own points say where it comes down (c
    # stands on d: a tower of two).
    features = np.stack([object_features("cube", np.array([0.89, 0.31, z]), np.eye(3))
                         for z in (0.025, 0.075)]
                        + [object_features("long", np.array([0.7, 0.0, 0.025]), np.eye(3))])
    scene = Boxes(("d", "c", "l"), features, frozenset()).moved(features[:, :3])
    assert set_down_tips(scene, Action("l", "right", "c", "center"))  # centre 7.5 cm off
    assert set_down_tips(scene, Action("l", "left", "c", "center"))
    assert not set_down_tips(scene, Action("l", "center", "c", "center"))  # centred
    assert not set_down_tips(scene, Action("l", "right", "c", "right"))  # offsets cancel
    assert not set_down_tips(scene, Action("c", "center", "l", "right"))  # on its end: held
    # on a cube on the table the block leans on the table (goals have blocks so)
    assert not set_down_tips(scene, Action("l", "right", "d", "center"))
    # traced (six boxes): a block picked up leaning (20 degrees) at its end and released
    # over a cube atop a tower fell just the same; the tilt it had is not the one it lands with
    leaning = scene.features.copy()
    leaning[2, 3] = np.cos(np.radians(20))
    scene = Boxes(scene.names, leaning, frozenset()).moved(leaning[:, :3])
    assert set_down_tips(scene, Action("l", "right", "c", "center"))
    assert not set_down_tips(scene, Action("l", "center", "c", "center"))


def test_a_load_near_its_one_supports_edge_falls_and_no_step_puts_it_there():
    # settled in full physics for 2 s from these positions: each `fell` scene toppled,
    # each `stood` one stood
    def scene(*where):  # (name, type, y, z) along one line
        features = np.stack([object_features(kind, np.array([0.7, y, z]), np.eye(3))
                             for _, kind, y, z in where])
        return Boxes(tuple(w[0] for w in where), features, frozenset()).moved(features[:, :3])

    c = ("c", "cube", 0.0, 0.025)
    fell = [scene(c, ("l", "long", 0.018, 0.075)),  # a block centred 1.8 cm off a cube
            scene(c, ("l", "long", 0.0, 0.075), ("t", "cube", -0.075, 0.125))]  # 1.5 cm
    stood = [scene(c, ("l", "long", 0.01, 0.075)),
             scene(c, ("l", "long", 0.0, 0.075), ("m", "long", 0.0, 0.125),
                   ("t", "cube", -0.075, 0.175)),  # 0.8 cm off
             scene(*[(f"c{k}", "cube", 0.003 * k, 0.025 + 0.05 * k) for k in range(5)])]
    for s in fell:
        assert unstable(s, ["t" if "t" in s.names else "l"]), s.names
        assert unstable(s, ["l"]) and overloaded(s, "l") and not overloaded(s, "c")
    for s in stood:
        assert not unstable(s, [s.names[-1]]), s.names
    # the first cube t on the end of the block on c: the step that puts it there is unsafe
    before = scene(c, ("l", "long", 0.0, 0.075), ("t", "cube", 0.2, 0.025))
    after = scene(c, ("l", "long", 0.0, 0.075), ("t", "cube", -0.075, 0.125))
    assert Refiner.topples(before, after)
    assert not Refiner.topples(before, scene(c, ("l", "long", 0.0, 0.075),
                                             ("t", "cube", 0.0, 0.125)))


def test_a_box_set_on_the_free_end_of_a_block_balanced_on_a_cube_topples_it():
    # traced (eight boxes): a cube let down on the end of a block balanced on a cube atop a
    # tower, a cube centred on the block, brought the tower down; its load is 1.25 cm off
    # the cube's centre, which stands where it is built without the blow
    def scene(*where):  # (name, type, y, z) along one line
        features = np.stack([object_features(kind, np.array([0.79, y, z]), np.eye(3))
                             for _, kind, y, z in where])
        return Boxes(tuple(w[0] for w in where), features, frozenset()).moved(features[:, :3])

    tower = [("c0", "cube", 0.14, 0.075), ("c1", "cube", 0.14, 0.125),
             ("l", "long", 0.14, 0.175), ("top", "cube", 0.14, 0.225),
             ("base", "long", 0.216, 0.025)]
    end = scene(*tower, ("s", "cube", 0.214, 0.225))
    assert on_overhang(end, "s") and unstable(end, ["s"])
    assert not overloaded(end, "l")  # not by statics alone
    centred = scene(*tower[:3], ("s", "cube", 0.14, 0.225), tower[4])
    assert not on_overhang(centred, "s") and not unstable(centred, ["s"])
    # across two cubes (a bridge) the block's end is held: no overhang
    bridge = scene(("a", "cube", 0.04, 0.025), ("b", "cube", 0.24, 0.025),
                   ("l", "long", 0.14, 0.075), ("s", "cube", 0.21, 0.125))
    assert not on_overhang(bridge, "s") and not unstable(bridge, ["s"])


def test_a_block_carrying_a_block_is_judged_where_both_come_down():
    # traced (eight boxes): pick(o4:left) place(o5:right), a block with a block on it
    # released 15 cm off a cube atop a tower (its end on the cube's edge: half a block and
    # half a cube), and block, rider and tower fell. The rider comes down with the block
    # (left where it was, it can read as a second support), the edge holds the block's end.
    where = {"c0": ("cube", (0.65, -0.16, 0.025)), "c1": ("cube", (0.65, -0.16, 0.075)),
             "l": ("long", (0.65, 0.18, 0.025)), "r": ("long", (0.65, 0.18, 0.075))}
    features = np.stack([object_features(kind, np.array(p), np.eye(3))
                         for kind, p in where.values()])
    scene = Boxes(tuple(where), features, frozenset()).moved(features[:, :3])
    assert set_down_tips(scene, Action("l", "left", "c1", "right"))
    assert not set_down_tips(scene, Action("l", "center", "c1", "center"))


def test_a_box_released_with_its_centre_beyond_its_one_support_topples_and_no_plan_goes_there():
    def scene(**where):  # name -> (type, position)
        features = np.stack([object_features(kind, np.array(p, float), np.eye(3))
                             for kind, p in where.values()])
        return Boxes(tuple(where), features, frozenset()).moved(features[:, :3])

    c = ("cube", (0.5, 0.0, 0.025))
    assert tips(scene(c=c, l=("long", (0.5, 0.075, 0.075))), "l")  # its end over c
    assert tips(scene(c=c, t=("cube", (0.5, 0.035, 0.075))), "t")  # 1 cm past c's edge
    assert not tips(scene(c=c, l=("long", (0.5, 0.02, 0.075))), "l")  # c under its centre
    assert not tips(scene(c=c, d=("cube", (0.5, 0.2, 0.025)), l=("long", (0.5, 0.1, 0.075))),
                    "l")  # a bridge: its centre between its two supports
    assert not tips(scene(c=c, l=("long", (0.5, 0.075, 0.025))), "l")  # on the table
    # a block leaning with one end on c (tilted 20 degrees): held by the table too
    leaning = object_features("long", np.array([0.5, 0.1, 0.05]),
                              np.array([[1, 0, 0], [0, 0.94, -0.342], [0, 0.342, 0.94]]))
    both = np.stack([object_features("cube", np.array(c[1]), np.eye(3)), leaning])
    assert not tips(Boxes(("c", "l"), both, frozenset()).moved(both[:, :3]), "l")
    # the hand-written model puts l's centre 7.5 cm off c's (a release at c's right): the
    # search reaches that scene without the rules (the prediction's and the action's own
    # points') and not with them
    start = scene(c=c, l=("long", (0.7, 0.2, 0.025)))
    goal = {"c": np.array(c[1]), "l": np.array([0.5, 0.075, 0.075])}
    refiner = Refiner(list(STACK.values()), Stacking())
    found, _ = refiner.search(start, goal, Budget.of_cpu(10))
    assert found is None
    refiner.unsafe = lambda before, after, action: False
    found, _ = refiner.search(start, goal, Budget.of_cpu(10))
    assert [(s.action.source, s.action.target) for s in found.steps] == [("l", "c")]


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


class Slow(Skeletons):
    """Skeletons whose planner takes 0.1 s a call."""

    def plan(self, *args, **kwargs):
        time.sleep(0.1)
        return super().plan(*args, **kwargs)


def test_each_candidate_reports_the_time_it_took():
    tower = boxes(a=(0.7, 0.0, 0.125), b=(0.7, 0.0, 0.075), c=(0.7, 0.0, 0.025))
    found = solve(Slow(Plan("unsolvable"), Plan("unsolvable")), tower)
    first, second, search = found.candidates
    assert first.seconds >= 0.1 and second.seconds >= 0.1
    assert first.seconds + second.seconds + search.seconds <= found.seconds
    assert search.to_json()["seconds"] == round(search.seconds, 4)


class Lifting(torch.nn.Module):
    """An effect model that says: the source rises 10 cm at the lift and comes down 5 cm
    above where the carry put it; the target and the rest do not move."""

    def forward(self, state, action, mask):
        effect = torch.zeros(*state.shape[:2], 6)
        source = action[:, :, 0] > 0.5
        effect[source] = torch.tensor([0.0, 0.0, 0.10, 0.0, 0.0, -0.05])
        return effect


def test_the_continuous_model_carries_a_lifted_box_to_the_release_point():
    model = ContinuousModel(Lifting())
    after = model.predict(START, [Action("a", "center", "c", "left")])[0].where()
    # a: up 10 cm, carried to c shifted 7.5 cm along -y, down 5 cm, its whole footprint
    # beside c's top: it falls to the table.
    assert np.allclose(after["a"], [0.7, -0.075, 0.025], atol=1e-6)
    assert np.allclose(after["c"], [0.7, 0.0, 0.025]) and np.allclose(after["b"], START.where()["b"])
    rolled = model.rollout(START, [Action("a", "center", "c", "center"),
                                   Action("b", "center", "a", "center")])
    # b is carried to where a was predicted to be; this model's heights ignore the target,
    # but b's centre is over a, so b comes to rest on a's top (continuous.rest).
    assert np.allclose(rolled[-1].where()["b"], [0.7, 0.0, 0.125], atol=1e-6)
    assert ("a", "c") in rolled[0].contacts  # contacts of the predicted scene


class Sliding(torch.nn.Module):
    """Lifting, with the source predicted to come down `dy` along y from the release and
    the target predicted to rise with it."""

    def __init__(self, dy: float):
        super().__init__()
        self.dy = dy

    def forward(self, state, action, mask):
        effect = torch.zeros(*state.shape[:2], 6)
        effect[action[:, :, 0] > 0.5] = torch.tensor([0.0, 0.0, 0.10, 0.0, self.dy, -0.05])
        effect[action[:, :, 1] > 0.5] = torch.tensor([0.0, 0.0, 0.10, 0.0, 0.0, -0.10])
        return effect


def test_a_carried_box_lands_at_its_release_unless_predicted_to_fall_off_it():
    def landed(dy):
        return ContinuousModel(Sliding(dy)).predict(
            START, [Action("a", "center", "c", "left")])[0].where()

    # measured (six boxes, 256 steps): the arm sets a box down 2 mm from its release
    # (median), the model's own guess 6 mm; a shift under SNAP is the regression's error
    assert np.allclose(landed(0.012)["a"][:2], [0.7, -0.075], atol=1e-6)
    assert np.allclose(landed(-0.08)["a"][:2], [0.7, -0.075], atol=1e-6)
    assert np.allclose(landed(0.15)["a"][:2], [0.7, 0.075], atol=1e-6)  # falls off: kept
    # the target, predicted to rise, is not carried: the hand holds the source only
    assert np.allclose(landed(0.0)["c"], [0.7, 0.0, 0.025], atol=1e-6)


class Jittering(Lifting):
    """Lifting, with every box the hand does not hold predicted 4 mm along x."""

    def forward(self, state, action, mask):
        effect = super().forward(state, action, mask)
        effect[action[:, :, 0] <= 0.5, 0] += 0.004
        return effect


def test_a_box_the_hand_leaves_stays_where_it_was():
    after = ContinuousModel(Jittering()).predict(START, [Action("a", "center", "c", "center")])
    assert np.allclose(after[0].where()["c"], START.where()["c"])  # the regression's jitter
    asked = ContinuousModel(Jittering(), snap=0.0).predict(
        START, [Action("a", "center", "c", "center")])  # as the explorer asks the members
    assert np.allclose(asked[0].where()["c"], START.where()["c"] + [0.004, 0.0, 0.0])


def test_a_box_over_no_box_rests_on_the_table_and_what_the_hand_carried_settles_last():
    from drake_symplan.abstraction.continuous import rest

    scene = boxes(a=(0.7, 0.0, 0.025), b=(0.7, 0.0, 0.09), c=(0.7, 0.2, 0.09))
    # c, released beside the stack and predicted 9 cm up, is over nothing: on the table
    out = rest(scene.positions.astype(float), scene.features, moved=[1, 2])
    assert np.allclose(out[:, 2], [0.025, 0.075, 0.025])
    # b carried onto a, a nudged by the model and predicted higher than b: a settles
    # first, b comes down on it
    nudged = boxes(a=(0.705, 0.0, 0.1), b=(0.7, 0.0, 0.06))
    out = rest(nudged.positions.astype(float), nudged.features, moved=[0, 1], carried={1})
    assert np.allclose(out[:, 2], [0.025, 0.075])


def test_a_box_predicted_over_another_rests_on_it_and_one_over_it_in_part_keeps_its_height():
    from drake_symplan.abstraction.continuous import rest

    scene = boxes(a=(0.7, 0.0, 0.025), b=(0.7, 0.0, 0.075), c=(0.7, 0.01, 0.089),
                  d=(0.5, 0.2, 0.04), e=(0.7, 0.04, 0.06))
    out = rest(scene.positions.astype(float), scene.features, moved=[2, 3, 4])
    # c, released over the tower a-b, predicted at a mean height no box rests at: on b.
    assert np.allclose(out[2], [0.7, 0.01, 0.125]) and np.allclose(out[:2], scene.positions[:2])
    assert np.allclose(out[3], [0.5, 0.2, 0.025])  # over nothing: on the table
    assert np.allclose(out[4], [0.7, 0.04, 0.06])  # its edge over a: it may lean, as predicted
    # The lowest moved box settles first: a tower predicted low all the way up stacks.
    low = boxes(a=(0.7, 0.0, 0.025), b=(0.7, 0.0, 0.06), c=(0.7, 0.0, 0.07))
    assert np.allclose(rest(low.positions.astype(float), low.features, [1, 2])[:, 2],
                       [0.025, 0.075, 0.125])


def test_with_nothing_verified_the_first_skeleton_runs_on_its_symbols():
    goal = boxes(a=(0.7, 0.0, 0.075), b=(0.5, -0.2, 0.025), c=(0.7, 0.0, 0.025))
    on_b = Plan("solved", [Step(STACK["center"], ("a", "b"))])
    refiner = Refiner(list(STACK.values()), Stacking(), extra_moves=0, max_depth=0)
    found = plan_bilevel(Skeletons(on_b), refiner, observed(START), observed(goal),
                         Budget(10.0, 30.0))
    assert found.solved and found.level == "symbolic" and found.steps == on_b.steps
    assert "runs on its symbols" in found.message
    assert [c.accepted for c in found.candidates] == [False, False, False]
    # not where the arm refused its first step in this scene (traced: a skeleton with no
    # other way was sent to the arm twelve times and refused each time)
    refiner.refusals.refuse(on_b.steps[0].action)
    found = plan_bilevel(Skeletons(on_b), refiner, observed(START), observed(goal),
                         Budget(10.0, 30.0))
    assert (found.status, found.steps) == ("timeout", [])


class Staying(torch.nn.Module):
    """An effect model that says: nothing moves (the grasp missed)."""

    def forward(self, state, action, mask):
        return torch.zeros(*state.shape[:2], 6)


def test_an_ensemble_predicts_its_members_mean_and_their_disagreement():
    model = ContinuousModel([Lifting(), Staying()])
    after = model.predict(START, [Action("a", "center", "c", "left")])[0]
    lifted, stayed = np.array([0.7, -0.075, 0.025]), np.array([0.5, 0.2, 0.025])
    assert np.allclose(after.where()["a"], (lifted + stayed) / 2, atol=1e-6)
    half = np.linalg.norm(lifted - stayed) / 2
    assert np.allclose(after.uncertainty(), [half, 0.0, 0.0], atol=1e-6)
    # Along a rollout the spreads add up as independent errors do.
    again = model.predict(after, [Action("a", "center", "c", "left")])[0]
    assert again.uncertainty()[0] > half
    assert ContinuousModel(Lifting()).predict(START, [Action("a", "center", "c", "left")]
                                              )[0].spread is None


class Unsure(Stacking):
    """Stacking, but unsure by 5 cm where a box released on the left lands."""

    def predict(self, scene: Boxes, actions: list[Action]) -> list[Boxes]:
        out = super().predict(scene, actions)
        return [after.moved(after.positions, np.where(
            np.array(scene.names) == a.source, 0.05 if a.release == "left" else 0.0, 0.0))
                for after, a in zip(out, actions, strict=True)]


def test_a_plan_whose_end_is_uncertain_is_not_accepted_however_close_its_mean():
    goal = boxes(a=(0.7, release_shift(Action("a", "center", "c", "left")), 0.075),
                 b=(0.5, -0.2, 0.025), c=(0.7, 0.0, 0.025))
    left = Plan("solved", [Step(STACK["left"], ("a", "c"))])
    sure = plan_bilevel(Skeletons(left), Refiner(list(STACK.values()), Stacking(),
                                                 extra_moves=0), observed(START), observed(goal),
                        Budget(10.0, 30.0))
    assert sure.level == "bilevel" and sure.candidates[0].errors_cm["a"] == 0.0
    unsure = plan_bilevel(Skeletons(left), Refiner(list(STACK.values()), Unsure(),
                                                   extra_moves=0, max_depth=0),
                          observed(START), observed(goal), Budget(10.0, 30.0))
    assert unsure.level == "symbolic"  # nothing verified: the skeleton runs on its symbols
    assert unsure.candidates[0].errors_cm["a"] == 5.0  # the mean on the goal, 5 cm unsure


def test_when_nothing_reaches_the_goal_the_steps_predicted_nearest_it_run():
    tower = boxes(a=(0.7, 0.0, 0.125), b=(0.7, 0.0, 0.075), c=(0.7, 0.0, 0.025))
    refiner = Refiner(list(STACK.values()), Stacking(), extra_moves=0, max_depth=1)
    found = plan_bilevel(Skeletons(Plan("solved", [])), refiner, observed(START),
                         observed(tower), Budget(10.0, 30.0))  # the goal's symbols hold already
    assert found.solved and found.level == "nearest" and "nearest" in found.message
    assert [s.action for s in found.steps] == [Action("b", "center", "c", "center")]
    # Nothing nearer than the start: the empty plan stands (the agent then fails honestly).
    assert not plan_bilevel(Skeletons(Plan("solved", [])), refiner, observed(START),
                            observed(START), Budget(10.0, 30.0)).steps


STACKED = boxes(a=(0.7, 0.0, 0.125), b=(0.7, 0.0, 0.075), c=(0.7, 0.0, 0.025))
BUILT = [Action("b", "center", "c", "center"), Action("a", "center", "b", "center")]


def test_a_goal_more_moves_away_than_a_skeleton_is_checked_for_is_searched_first(monkeypatch):
    monkeypatch.setattr(bilevel, "LONG_GOAL", 1)  # the tower is 2 moves away by its order
    skeleton = Plan("solved", [Step(STACK["center"], ("b", "c")),
                               Step(STACK["center"], ("a", "b"))])
    planner = Skeletons(skeleton)
    found = solve(planner, STACKED)
    assert found.level == "continuous" and [s.action for s in found.steps] == BUILT
    assert [c.source for c in found.candidates] == ["continuous"] and planner.plans
    # Where the search finds nothing the skeletons come after it, in what is left.
    refiner = Refiner(list(STACK.values()), Stacking(), max_depth=1)
    found = plan_bilevel(Skeletons(skeleton), refiner, observed(START), observed(STACKED),
                         Budget(10.0, 30.0))
    assert found.level == "bilevel" and [s.action for s in found.steps] == BUILT
    assert [c.source for c in found.candidates] == ["continuous", "skeleton 1"]
    # A receding horizon keeps the skeletons first (its subgoals are theirs).
    assert solve(Skeletons(skeleton), STACKED, horizon=1).level == "receding"


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
    planner = object.__new__(BilevelMode)  # the monitor alone: no abstraction needed
    planner.refiner = Refiner(list(STACK.values()), Stacking())
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

    class AtomsHold:
        def goal_holds(self, reading, atoms):
            return True  # the symbols say "a on b" for both scenes

    for planning, seen in (("symbolic", True), ("bilevel", False), ("continuous", False)):
        planner = object.__new__(PLANNING_MODES[planning])
        planner.abs = AtomsHold()
        planner.last = Plan("solved", level="symbolic")  # a skeleton run on its symbols
        assert planner.goal_seen(observe(Seen(off)), frozenset(), observe(Seen(goal))) is seen
        assert planner.goal_seen(observe(Seen(goal)), frozenset(), observe(Seen(goal)))


def observe(scene: Seen) -> Observation:
    """A perceived scene as the monitor gets it (no symbols read)."""
    return Observation(scene, None, Boxes.of(scene))


def test_each_mode_is_one_registered_class_whose_flags_say_what_it_needs():
    from drake_symplan.agent.config import SolveConfig
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


TOWER = boxes(a=(0.7, 0.0, 0.075), b=(0.7, 0.0, 0.125), c=(0.7, 0.0, 0.025))


def test_a_long_skeleton_is_refined_to_its_subgoal_one_step_at_a_time():
    # Two skeletons for the tower b on a on c; the first puts a on b, which the rest
    # (b onto a) leaves there, off a's goal: its subgoal is missed.
    wrong = Plan("solved", [Step(STACK["center"], ("a", "b")), Step(STACK["center"], ("b", "a"))])
    right = Plan("solved", [Step(STACK["center"], ("a", "c")), Step(STACK["center"], ("b", "a"))])
    found = solve(Skeletons(wrong, right), TOWER, horizon=1)
    assert found.solved and found.level == "receding" and found.subgoal
    assert [s.action for s in found.steps] == [Action("a", "center", "c", "center")]
    assert np.allclose(found.predicted[-1].where()["a"], [0.7, 0.0, 0.075])
    first, second = found.candidates
    assert not first.accepted and "subgoal" in first.why
    assert second.accepted and second.why == "the first 1 of 2 steps, to their subgoal"
    assert second.to_json()["rest"] == [str(Step(STACK["center"], ("b", "a")))]
    # Without a horizon the same skeleton is refined whole: both steps, checked at the end.
    whole = solve(Skeletons(wrong, right), TOWER)
    assert whole.level == "bilevel" and not whole.subgoal and len(whole.steps) == 2
    # A skeleton no longer than the horizon is refined whole too.
    last = solve(Skeletons(Plan("solved", [Step(STACK["center"], ("b", "a"))])),
                 boxes(a=(0.5, 0.2, 0.025), b=(0.5, 0.2, 0.075), c=(0.7, 0.0, 0.025)),
                 horizon=1)
    assert last.level == "bilevel" and len(last.steps) == 1


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


def test_a_step_that_missed_its_prediction_makes_its_move_dearer_in_later_plans():
    planner = object.__new__(BilevelMode)  # the monitor's side alone (the default mode)
    planner.penalties = Counter()
    planner.refiner = Refiner(list(STACK.values()), Stacking())
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


class SymbolsHold(Skeletons):
    """An abstraction whose symbols always come true (mismatches finds none)."""

    def mismatches(self, reading, step):
        return set()


def test_a_step_after_which_nothing_moved_is_missed_though_its_symbols_hold():
    planner = object.__new__(BilevelMode)  # the monitor's side alone
    planner.abs, planner.penalties = SymbolsHold(), Counter()
    planner.refiner = Refiner(list(STACK.values()), Stacking())
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


@pytest.mark.slow
def test_a_move_the_arm_missed_is_taken_another_way_in_later_searches():
    planner = object.__new__(BilevelMode)  # the monitor's side alone
    planner.refiner = Refiner(list(STACK.values()), Stacking(), defer=None)
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
    planner.penalties = Counter()
    planner.refused(move)
    assert planner.refiner.refusals.keys == {("grasp", "a", "center")}
    found, _ = planner.refiner.search(side, goal, Budget.of_cpu(10))
    assert found is None  # every move of a grasps its centre
    far = boxes(a=(0.5, 0.2, 0.025), b=(0.5, -0.3, 0.025), c=(0.7, 0.0, 0.025))  # b, 40 cm
    planner.observed(move, predicted, before, observe(Seen(far)))
    assert planner.refiner.refusals.keys == {("grasp", "a", "center")}
    planner.observed(move, predicted, before, observe(Seen(predicted)))
    assert not planner.refiner.refusals.keys
