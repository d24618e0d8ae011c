"""Bilevel planning (abstraction/bilevel.py): skeletons searched and accepted, the fallbacks."""

from __future__ import annotations

import time

import numpy as np
from bilevel_fixtures import (
    STACK,
    START,
    TOWER,
    Penalized,
    Skeletons,
    Stacking,
    boxes,
    observed,
    solve,
)

from drake_symplan.abstraction import bilevel
from drake_symplan.abstraction.abstraction import Plan
from drake_symplan.abstraction.bilevel import PENALTY, plan_bilevel
from drake_symplan.abstraction.continuous import Boxes
from drake_symplan.abstraction.refiner import Refiner
from drake_symplan.actions import Action, release_shift
from drake_symplan.planning.budget import Budget
from drake_symplan.symbolic.structs import Reposition, Step


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


def test_the_continuous_fallback_finds_a_two_step_plan_the_symbols_cannot():
    tower = boxes(a=(0.7, 0.0, 0.125), b=(0.7, 0.0, 0.075), c=(0.7, 0.0, 0.025))
    found = solve(Skeletons(Plan("unsolvable"), Plan("unsolvable")), tower)
    assert found.solved and found.level == "continuous"
    assert [s.action for s in found.steps] == [Action("b", "center", "c", "center"),
                                               Action("a", "center", "b", "center")]
    assert all(isinstance(s, Reposition) and s.kind == "move" for s in found.steps)
    assert [c.source for c in found.candidates] == ["skeleton 1", "skeleton 2", "continuous"]
    assert solve(Skeletons(), tower, skeletons=False).steps == found.steps


def test_a_skeleton_longer_than_the_boxes_off_their_goal_gives_way_to_a_shorter_search():
    goal = boxes(a=(0.7, 0.0, 0.075), b=(0.5, -0.2, 0.025), c=(0.7, 0.0, 0.025))
    detour = Plan("solved", [Step(STACK["center"], ("a", "b")), Step(STACK["center"], ("a", "c"))])
    found = solve(Skeletons(detour), goal)  # one box off its goal, a skeleton of two steps
    assert found.solved and found.level == "continuous"
    assert [s.action for s in found.steps] == [Action("a", "center", "c", "center")]
    skeleton, search = found.candidates
    assert skeleton.accepted and len(skeleton.steps) == 2
    assert search.accepted and search.why == "1 step where the refined skeleton takes 2"


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


def test_skeletons_are_planned_knowing_which_named_pairs_the_start_does_not_hold():
    from types import SimpleNamespace

    from drake_symplan.abstraction.abstraction import Observation
    from drake_symplan.relations import parse

    class Asked(Skeletons):
        def plan(self, start, goal, planner, budget, focus=True, penalties=None,
                 unheld=frozenset()):
            self.unheld = unheld
            return Plan("unsolvable")

    # the start: a, b and c apart; the goal: a on b on c, of which b on c already holds
    start = boxes(a=(0.5, 0.2, 0.025), b=(0.7, 0.0, 0.075), c=(0.7, 0.0, 0.025))
    reading = SimpleNamespace(kinds={("a", "b"): "on", ("b", "c"): "on"})
    goal = Observation(None, reading, TOWER, tuple(parse(["tower a b c"])))
    asked = Asked()
    plan_bilevel(asked, Refiner(list(STACK.values()), Stacking()), observed(start), goal,
                 Budget(2.0, 6.0))
    assert asked.unheld == {("a", "b")}
