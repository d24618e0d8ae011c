"""Goals of relations in planning (abstraction/relation_goal.py): judged wherever the
structure stands, planned from the bottom up, at up to 16 boxes."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest
from bilevel_fixtures import STACK, Skeletons, Stacking, boxes, observed, solve
from bilevel_fixtures import START as BOXES
from conftest import run

from drake_symplan.abstraction.abstraction import Abstraction, Observation, Plan, Reading
from drake_symplan.abstraction.bilevel import Search, plan_bilevel
from drake_symplan.abstraction.goal_plans import plan_goal, stages
from drake_symplan.abstraction.refiner import Refiner
from drake_symplan.abstraction.relation_goal import (
    BASES,
    pair_choices,
    relation_goal,
    relation_pairs,
    unheld,
    unheld_readings,
)
from drake_symplan.boxes import CONTACT_TOLERANCE, VICINITY
from drake_symplan.planning.budget import Budget
from drake_symplan.relations import parse
from drake_symplan.symbolic.states import SymbolicState
from drake_symplan.symbolic.structs import Goal, Step, Task
from drake_symplan.world.scenes import ObjectSpec, Scene, save_scene

# The example built c at (0.6, 0.1) with a on it; the skeleton leaves c where it stands.
EXAMPLE = boxes(a=(0.6, 0.1, 0.075), b=(0.5, -0.2, 0.025), c=(0.6, 0.1, 0.025))
A_ON_C = Plan("solved", [Step(STACK["center"], ("a", "c"))])


@pytest.mark.slow
def test_a_skeleton_that_builds_the_relation_elsewhere_is_accepted_for_a_relation_goal():
    scene_goal = solve(Skeletons(A_ON_C), EXAMPLE)
    assert not scene_goal.candidates[0].accepted  # a and c 14 cm off the example
    goal = relation_goal(observed(EXAMPLE), parse(["on a c"]))
    assert goal.boxes.names == ("a", "c")  # b is free
    refiner = Refiner(list(STACK.values()), Stacking())
    found = plan_bilevel(Skeletons(A_ON_C), refiner, observed(BOXES), goal, Budget(10.0, 30.0),
                         Search(True))
    assert found.solved and found.level == "bilevel" and found.candidates[0].accepted
    assert [str(s) for s in found.steps] == [str(A_ON_C.steps[0])]


def test_a_relation_goal_is_reached_by_its_relations_not_by_boxes_near_the_example():
    refiner = Refiner(list(STACK.values()), Stacking())
    refiner.relations = tuple(parse(["row a b"]))
    example = boxes(a=(0.6, 0.0, 0.025), b=(0.6, 0.06, 0.025))
    # b 3 cm across from a: each box within 3 cm of the example's place, and no row
    askew = boxes(a=(0.6, 0.0, 0.025), b=(0.63, 0.06, 0.025))
    assert not refiner.reached(askew, example.where())
    # the same row 20 cm from the example holds
    elsewhere = boxes(a=(0.5, -0.2, 0.025), b=(0.5, -0.14, 0.025))
    assert refiner.reached(elsewhere, example.where())


def test_a_relation_goal_names_its_pairs_upper_first_with_the_lower_boxs_layer():
    tower = boxes(a=(0.6, 0.1, 0.125), b=(0.6, 0.1, 0.075), c=(0.6, 0.1, 0.025),
                  d=(0.8, 0.0, 0.025))
    reading = Reading(SymbolicState(tower.names, np.zeros((4, 1)), np.zeros((3, 4, 4))),
                      np.zeros((4, 1), bool), np.zeros((3, 4, 4), bool))
    goal = relation_goal(Observation(None, reading, tower), parse(["tower a b c"]))
    assert goal.reading.pairs == {("b", "c"): (0, 0, 0), ("a", "b"): (1, 0, 0)}


def test_a_goal_of_relations_is_planned_in_stages_from_the_lowest_pairs():
    # tower a b c, and on d e: c and e on the table
    goal = SimpleNamespace(pairs={("b", "c"): (0, 0), ("a", "b"): (1, 0), ("d", "e"): (0, 1)})
    atoms = frozenset({("r0", "a", "b"), ("r0", "b", "c"), ("not_r2", "b", "c"),
                       ("r0", "d", "e")})
    bottom = frozenset({("r0", "b", "c"), ("not_r2", "b", "c")})
    assert stages(goal, atoms) == [
        bottom, bottom | {("r0", "d", "e")}, atoms]


def test_a_rows_pairs_are_staged_one_by_one_from_its_first_box():
    # row a b c on the table: b beside a first, then c beside b (planned at once, c was
    # laid beside b and b then moved beside a, leaving c behind)
    pairs, _ = relation_pairs(parse(["row a b c"]), Scene([
        ObjectSpec("a", "cube", [0.6, 0.0, 0.025]), ObjectSpec("b", "cube", [0.6, 0.07, 0.025]),
        ObjectSpec("c", "cube", [0.6, 0.14, 0.025])]).object_states())
    assert pairs == {("a", "b"): (0, 0, 0), ("b", "c"): (0, 0, 1)}
    first, second = {("r1", "a", "b")}, {("r1", "b", "c")}
    assert stages(SimpleNamespace(pairs=pairs), frozenset(first | second)) == [
        first, first | second]


def test_a_reading_the_start_holds_where_the_relation_does_not_is_no_goal():
    # b on c, read by the example as c and b apart (r1 both ways); the start has them
    # apart and reads the same: that reading is dropped, the pattern stays
    apart = frozenset({("r1", "b", "c"), ("r1", "c", "b")})
    on = frozenset({("r0", "b", "c"), ("r1", "c", "b")})
    goal = Goal({("r0", "a", "b")}, [(("b", "c"), [apart, on])])
    start = apart | {("r0", "a", "b")}
    kept = unheld_readings(goal, start, frozenset({("b", "c")}))
    assert kept.choices == ((("b", "c"), (on,)),) and set(kept) == {("r0", "a", "b")}
    assert unheld_readings(goal, start, frozenset()).choices == goal.choices  # it holds
    assert unheld_readings(goal, start | on, frozenset({("b", "c")})).choices == goal.choices
    objects = Scene([ObjectSpec("b", "cube", [0.6, 0.2, 0.025]),
                     ObjectSpec("c", "cube", [0.6, 0.0, 0.025])]).object_states()
    reading = SimpleNamespace(kinds={("b", "c"): "on"})
    assert unheld(reading, objects) == {("b", "c")}
    stacked = {**objects, "b": Scene([ObjectSpec("b", "cube", [0.6, 0.0, 0.075])]
                                     ).object_states()["b"]}
    assert unheld(reading, stacked) == set()


class UnaryOnly:
    """Semantics of a model with unary symbols alone (Attentive): u0 of a and c, one
    neighbour of b."""

    def read(self, *args, **kwargs):
        return {("u0", 0), ("u0", 2), ("touching1", 1)}, set()


def test_a_model_without_relations_keeps_the_named_objects_atoms_of_a_relation_goal():
    names = ("a", "b", "c")
    reading = Reading(SymbolicState(names, np.zeros((3, 1)), np.zeros((0, 3, 3))),
                      np.zeros((3, 1), bool), np.zeros((0, 3, 3), bool),
                      pairs={("a", "b"): (0, 0)})
    bundle = SimpleNamespace(n_relations=0, semantics=UnaryOnly())
    atoms = Abstraction(bundle).goal_atoms(reading)
    assert atoms == {("u0", "a"), ("touching1", "b")}  # c is not named: free
    assert stages(reading, atoms) == [atoms]


class RowBits:
    """Semantics reading a row a b (b beside a) as on and beside read in the learned bits:
    r1 r2 from a to b, r0 from b to a; c on the table apart, in relation to nothing."""

    def read(self, *args, **kwargs):
        return {("r1", 0, 1), ("r2", 0, 1), ("r0", 1, 0), ("r0", 2, 0), ("u0", 0)}, set()


def test_under_vicinity_a_named_pairs_relation_is_its_bits_both_ways_and_no_other_pairs():
    names = ("a", "b", "c")
    reading = Reading(SymbolicState(names, np.zeros((3, 1)), np.zeros((3, 3, 3))),
                      np.zeros((3, 1), bool), np.zeros((3, 3, 3), bool),
                      pairs={("a", "b"): (0, 0)})
    vicinity = Abstraction(SimpleNamespace(n_relations=3, semantics=RowBits(),
                                           relevance_radius=VICINITY, patterns={}))
    atoms = vicinity.goal_atoms(reading)
    assert atoms == {("r1", "a", "b"), ("r2", "a", "b"), ("r0", "b", "a")}
    assert stages(reading, atoms) == [atoms]
    contact = Abstraction(SimpleNamespace(n_relations=3, semantics=RowBits(),
                                          relevance_radius=CONTACT_TOLERANCE, patterns={}))
    assert contact.goal_atoms(reading) == {("r1", "a", "b"), ("r2", "a", "b")}


def test_a_pair_whose_kind_the_symbols_read_in_patterns_is_a_choice_of_them():
    # the example reads a b's bits as RowBits does; the bundle reads "on" in two patterns
    # (relation_patterns.py): a on b is a choice of the example's bits or either pattern,
    # held wherever one of them holds, and in the stage of its pair
    names = ("a", "b", "c")
    reading = Reading(SymbolicState(names, np.zeros((3, 1)), np.zeros((3, 3, 3))),
                      np.zeros((3, 1), bool), np.zeros((3, 3, 3), bool),
                      pairs={("a", "b"): (0, 0)}, kinds={("a", "b"): "on"})
    on = [frozenset({("r0", 0, 1), ("not_r0", 1, 0)}), frozenset({("r1", 0, 1)})]
    vicinity = Abstraction(SimpleNamespace(n_relations=3, semantics=RowBits(),
                                           relevance_radius=VICINITY, patterns={"on": on}))
    goal = vicinity.goal_atoms(reading)
    example = {("r1", "a", "b"), ("r2", "a", "b"), ("r0", "b", "a")}
    assert goal == set() and goal.choices == ((("a", "b"), (
        example, {("r0", "a", "b"), ("not_r0", "b", "a")}, {("r1", "a", "b")})),)
    assert goal <= {("r1", "a", "b"), ("r0", "c", "a")}  # the second pattern holds
    assert not goal <= {("r0", "a", "b"), ("r0", "b", "a")}  # the first but for not_r0
    assert stages(reading, goal) == [goal] and stages(
        reading, goal)[0].choices == goal.choices



def test_a_bridge_on_towers_names_its_towers_bottoms_first_and_one_on_the_table_does_not():
    # l bears on a and b, which stand on c and d, 7.5 cm apart along y
    built = Scene([ObjectSpec("a", "cube", [0.6, 0.1, 0.075]),
                   ObjectSpec("b", "cube", [0.6, 0.175, 0.075]),
                   ObjectSpec("c", "cube", [0.6, 0.1, 0.025]),
                   ObjectSpec("d", "cube", [0.6, 0.175, 0.025]),
                   ObjectSpec("l", "long", [0.6, 0.14, 0.125])]).object_states()
    pairs, kinds = relation_pairs(parse(["tower a c", "tower b d", "bridge l a b"]), built)
    assert pairs == {("a", "c"): (0, 0, 0), ("b", "d"): (0, 1, 0), ("l", "a"): (1, 2, 0),
                     ("l", "b"): (1, 2, 0), ("c", "d"): (0, BASES, 0)}
    assert ("c", "d") not in kinds and kinds[("l", "a")] == "bears"
    on_table = Scene([ObjectSpec("c", "cube", [0.6, 0.1, 0.025]),
                      ObjectSpec("d", "cube", [0.6, 0.175, 0.025]),
                      ObjectSpec("l", "long", [0.6, 0.14, 0.075])]).object_states()
    pairs, _ = relation_pairs(parse(["bridge l c d"]), on_table)
    assert pairs == {("l", "c"): (0, 0, 0), ("l", "d"): (0, 0, 0)}


def test_a_bears_pair_may_also_read_what_its_example_and_patterns_share_an_on_pair_not():
    example = {("r0", "l", "a"), ("r1", "a", "l"), ("r2", "l", "a")}
    patterns = [frozenset({("r1", 1, 0), ("r2", 0, 1), ("not_r0", 1, 0)}),
                frozenset({("r0", 0, 1), ("r1", 1, 0), ("r2", 0, 1), ("not_r2", 1, 0)})]
    goal = pair_choices({("l", "a"): "bears"}, frozenset(example), {"bears": patterns})
    (_, readings), = goal.choices
    assert readings[-1] == {("r1", "a", "l"), ("r2", "l", "a")} and len(readings) == 4
    assert goal <= {("r1", "a", "l"), ("r2", "l", "a")}
    on = pair_choices({("l", "a"): "on"}, frozenset(example), {"on": patterns})
    assert len(on.choices[0][1]) == 3 and not on <= {("r1", "a", "l"), ("r2", "l", "a")}


def test_where_a_later_stage_has_no_plan_the_first_stages_plan_runs_and_the_rest_waits(
        monkeypatch):
    # tower a b c: stage one (b on c) has a plan, stage two (a on b) none; nor has the
    # goal at once: the plan of stage one, level "staged", ends at a subgoal
    step = Step(STACK["center"], ("b", "c"))
    found = {"at once": Plan("timeout")}

    def focused(self, task, start, goal, planner, budget, focus, penalties, bound=None):
        if len(task.goal) == 2:
            return found["at once"]
        return Plan("solved", [step]) if ("r0", "b", "c") in task.goal else Plan("timeout")

    monkeypatch.setattr(Abstraction, "plan_focused", focused)
    abstraction = Abstraction(None)
    reading = SimpleNamespace(pairs={("b", "c"): (0, 0), ("a", "b"): (1, 0)})
    task = Task(("a", "b", "c"), frozenset(), Goal([("r0", "b", "c"), ("r0", "a", "b")]))
    plan = plan_goal(abstraction, task, reading, reading, Budget.of_cpu(1.0), "fd", True, {})
    assert plan.solved and plan.steps == [step] and plan.level == "staged" and plan.subgoal
    found["at once"] = Plan("solved", [step, step])  # the goal at once: that plan
    plan = plan_goal(abstraction, task, reading, reading, Budget.of_cpu(1.0), "fd", True, {})
    assert plan.steps == [step, step] and not plan.subgoal



def test_a_plan_of_first_stages_is_no_skeleton_for_bilevel_planning():
    from drake_symplan.abstraction.bilevel import skeletons

    staged = Plan("solved", [Step(STACK["center"], ("b", "c"))], level="staged")
    abstraction = SimpleNamespace(plan=lambda *args, **options: staged)
    first = next(skeletons(abstraction, None, None, "fd", Budget.of_cpu(1.0)))
    assert not first.solved and first.steps == [] and staged.solved



def test_a_stage_is_planned_on_the_boxes_touching_what_it_changes_first_then_more(
        monkeypatch):
    from drake_symplan.abstraction import abstraction as module
    from drake_symplan.planning.planners import PlanResult

    tried, answers = [], []

    def planned(operators, domain, task, *args, **options):
        tried.append(task.objects)
        return answers.pop(0)

    monkeypatch.setattr(module, "plan_task", planned)
    abstraction = Abstraction(SimpleNamespace(planned=[], domain_for=lambda *a: ""))
    # a on b wanted; c touches a at the start, d is near b (related under vicinity), e apart
    start = SimpleNamespace(contacts={("a", "c"), ("b", "d")}, touching={("a", "c")})
    goal = SimpleNamespace(contacts=set(), touching=set(), pairs=None)
    task = Task(tuple("abcde"), frozenset(), Goal([("r0", "a", "b")]))
    answers[:] = [PlanResult("solved", [], 0.0, "", "fd")]
    abstraction.plan_focused(task, start, goal, budget=Budget.of_cpu(1.0))
    assert tried == [("a", "b", "c")]  # a plan over those holds for every box
    tried.clear()
    answers[:] = [PlanResult("unsolvable", [], 0.0, "", "fd"),
                  PlanResult("unsolvable", [], 0.0, "", "fd"),
                  PlanResult("timeout", [], 0.0, "", "fd")]
    abstraction.plan_focused(task, start, goal, budget=Budget.of_cpu(1.0))
    assert tried == [("a", "b", "c"), ("a", "b", "c", "d"), tuple("abcde")]


START = Scene([ObjectSpec("o0", "cube", [0.60, -0.25, 0.025]),
               ObjectSpec("o1", "long", [0.80, 0.10, 0.025]),
               ObjectSpec("o2", "cube", [0.60, 0.05, 0.025]),
               ObjectSpec("o3", "cube", [0.75, -0.20, 0.025])])


@pytest.mark.slow
def test_the_symbols_alone_build_a_written_tower_from_the_bottom_up(tmp_path, capsys):
    save_scene(START, tmp_path / "start.yaml")
    code, out, err = run(["solve", "--start", tmp_path / "start.yaml", "--goal-spec",
                          "tower o2 o3 o0", "--planning", "symbolic", "--backend", "hand",
                          "--json"], capsys)
    result = json.loads(out)
    assert code == 0 and result["status"] == "success", err
    assert result["relations"] == {"unmet": [], "unmet_true": []}
    assert [step.split()[1:] for step in result["plan"]][0][:2] == ["o3", "o0)"]


@pytest.mark.slow
def test_a_sixteen_box_scene_is_perceived_and_a_tower_on_it_planned_and_built(tmp_path,
                                                                              capsys):
    code, _, err = run(["scene", "sample", "--objects", "16", "--long-fraction", "0.25",
                        "--seed", "1", "--out", tmp_path / "s16.yaml"], capsys)
    assert code == 0, err
    code, out, err = run(["perceive", "--scene", tmp_path / "s16.yaml", "--json"], capsys)
    seen = json.loads(out)
    assert code == 0 and seen["count_ok"] and len(seen["objects"]) == 16, err
    code, out, err = run(["solve", "--start", tmp_path / "s16.yaml", "--goal-spec",
                          "tower o3 o7 o12", "--planning", "symbolic", "--backend", "hand",
                          "--json"], capsys)
    result = json.loads(out)
    assert code == 0 and result["relations"]["unmet"] == [], err
