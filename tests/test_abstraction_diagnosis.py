"""The symbols' stages of a goal of relations (abstraction/diagnosis.py): the steps nearest
a stage, with the atoms each lacks, on hand-made operators with a known answer; the
stages of a tower on the shipped model, from scenes perceived by hand (no Drake)."""

from __future__ import annotations

from conftest import bundle_for_tests
from test_relation_order import perceived

from drake_symplan.abstraction.abstraction import Abstraction
from drake_symplan.abstraction.diagnosis import diagnose, nearest_steps
from drake_symplan.abstraction.relation_goal import relation_goal
from drake_symplan.relations import parse
from drake_symplan.symbolic.bundle import ModelBundle
from drake_symplan.symbolic.structs import Atom, LiftedOperator
from drake_symplan.world.scenes import ObjectSpec

# Puts ?o0 on ?o1 where nothing touches ?o1: relates the source to its target alone.
ON = LiftedOperator(0, "center", "center", 2, (("touching0", 1),), (("r0", 0, 1),), (),
                    10, 10, 10)
# Spans ?o1 and ?o2, which must stand side by side (r1): relates the source to both.
SPAN = LiftedOperator(1, "center", "center", 3, (("r1", 1, 2),),
                      (("r0", 0, 1), ("r0", 0, 2), ("r2", 0, 2)), (), 10, 10, 10)


def test_the_nearest_steps_name_what_each_lacks():
    state = frozenset({Atom("touching0", "b"), Atom("touching0", "c")})
    goal = frozenset({Atom("r0", "a", "b"), Atom("r0", "a", "c"), Atom("r2", "a", "c")})
    first, second = nearest_steps([ON, SPAN], state, goal, ("a", "b", "c"), most=2)
    # the span reaches the whole goal but asks its supports to stand side by side
    assert first.step == f"({SPAN.name} a b c)"
    assert first.missing_pre == ["r1(b, c)"] and first.missing_goal == []
    # a place on one support lacks nothing to run and leaves the other's atoms unmet
    assert second.step == f"({ON.name} a b)"
    assert second.missing_pre == [] and second.missing_goal == ["r0(a, c)", "r2(a, c)"]


def test_a_state_that_holds_the_goal_needs_no_step():
    goal = frozenset({Atom("r0", "a", "b")})
    assert nearest_steps([ON, SPAN], goal, goal, ("a", "b", "c")) == []


# Four cubes apart on the table; the example: o0 on o1 on o2, o3 where it stood.
START = [ObjectSpec("o0", "cube", [0.55, -0.20, 0.025]),
         ObjectSpec("o1", "cube", [0.65, 0.00, 0.025]),
         ObjectSpec("o2", "cube", [0.75, 0.20, 0.025]),
         ObjectSpec("o3", "cube", [0.55, 0.20, 0.025])]
TOWER = [ObjectSpec("o0", "cube", [0.75, 0.20, 0.125]),
         ObjectSpec("o1", "cube", [0.75, 0.20, 0.075]),
         ObjectSpec("o2", "cube", [0.75, 0.20, 0.025]),
         ObjectSpec("o3", "cube", [0.55, 0.20, 0.025])]


def _tower_stages(cpu_seconds: float):
    abstraction = Abstraction(ModelBundle.load(bundle_for_tests()))
    start = abstraction.read_scene(perceived(START, []))
    example = abstraction.observe(perceived(TOWER, [("o0", "o1"), ("o1", "o2")]))
    goal = relation_goal(example, parse(["tower o0 o1 o2"]))
    return diagnose(abstraction, start, goal, cpu_seconds=cpu_seconds)


def test_a_tower_is_planned_from_the_bottom_up_one_pair_a_stage():
    first, second = _tower_stages(10.0)
    assert first.relations == second.relations == ["tower o0 o1 o2"]
    # the lower pair first: its atoms name o1 and o2 alone, the upper pair's o0 and o1
    assert all({"o1", "o2"} >= set(_objects(a)) for a in first.atoms)
    assert all({"o0", "o1"} >= set(_objects(a)) for a in second.atoms)
    assert first.status == second.status == "solved" and first.steps and second.steps


def test_a_stage_out_of_time_names_its_nearest_steps():
    (stage,) = _tower_stages(1e-4)
    assert stage.status != "solved" and stage.steps == []
    assert stage.nearest and all(n.missing_goal != sorted(stage.atoms) for n in stage.nearest)


def _objects(text: str) -> list[str]:
    """The objects of an atom's text, 'r0(o1, o2)' -> ['o1', 'o2']."""
    return text[text.index("(") + 1:-1].split(", ")
