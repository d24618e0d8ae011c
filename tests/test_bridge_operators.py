"""A bridge over two cubes on the symbols alone: models/vicinity_bridges, models/vicinity_general
extended with the operators the bridges_table recipe's data taught that span two boxes
(symbolic/bundle.extend_operators), lays a block across two cubes in one move."""

from __future__ import annotations

import pytest
from conftest import REPO

from drake_symplan.planning.grounding import fast_downward_task
from drake_symplan.planning.planners import search_binary
from drake_symplan.symbolic import relation_patterns
from drake_symplan.symbolic.bundle import ModelBundle, extend_operators, spans
from drake_symplan.symbolic.structs import Atom, Goal, LiftedOperator, Task, parse_step

# place ?o0 on ?o1: relates the moved box to one other.
PLACE = LiftedOperator(0, "center", "center", 2, (("p0", 0),), (("r0", 0, 1),), (), 20)
# lay ?o0 across ?o1 and ?o2 (which stand side by side): relates it to both at once.
ACROSS = LiftedOperator(3, "center", "left", 3, (("p0", 0), ("r1", 1, 2)),
                        (("r0", 0, 1), ("r1", 2, 0)), (), 12)
# ?o0 set beside ?o1 while ?o2 stands near: its effect names one pair only.
BESIDE = LiftedOperator(4, "center", "right", 3, (("p0", 0), ("r1", 1, 2)),
                        (("r1", 0, 1), ("touching1", 2)), (), 15)


def test_an_operator_spans_where_its_effect_relates_the_moved_box_to_two_others():
    assert spans(ACROSS) and not spans(PLACE) and not spans(BESIDE)


def test_extending_keeps_the_bundles_operators_and_adds_the_spanning_ones_numbered_after():
    extended = extend_operators([PLACE], [PLACE, BESIDE, ACROSS])
    assert [op.index for op in extended] == [0, 1]
    assert extended[0] is PLACE
    assert (extended[1].pre, extended[1].add, extended[1].count) == \
        (ACROSS.pre, ACROSS.add, ACROSS.count)

# The written set's bridge2/o6/p001 ("bridge o1 o4 o0") as perceived at its start: six
# boxes scattered, each free (p0) and touching nothing.
OBJECTS = tuple(f"o{i}" for i in range(6))
SCATTERED = frozenset([Atom("p0", o) for o in OBJECTS] + [Atom("touching0", o) for o in OBJECTS])
# What its compiled example (o0 set beside o4, o1 across both) reads of each pair the bridge
# names: the block's relation bits with each support, certain bits only.
EXAMPLE = {("o1", "o4"): {Atom("not_r0", "o4", "o1"), Atom("r1", "o1", "o4"),
                          Atom("r1", "o4", "o1")},
           ("o1", "o0"): {Atom("not_r0", "o0", "o1"), Atom("not_r2", "o0", "o1"),
                          Atom("r1", "o0", "o1"), Atom("r1", "o1", "o0")}}


@pytest.mark.skipif(search_binary() is None, reason="up-fast-downward has no search binary")
def test_the_generalized_bundle_brings_a_support_beside_and_lays_the_block_across_both():
    bundle = ModelBundle.load(REPO / "models/vicinity_bridges")
    patterns = bundle.patterns["bears"]
    choices = [(pair, [own, *(relation_patterns.ground(p, *pair) for p in patterns)])
               for pair, own in EXAMPLE.items()]
    found = fast_downward_task(bundle.planned, Task(OBJECTS, SCATTERED, Goal((), choices)),
                               60, cpu_seconds=30)
    assert found.status == "solved"
    beside, across = (parse_step(s, bundle.by_name) for s in found.plan)
    assert set(beside.args) == {"o0", "o4"}  # one cube set beside the other
    assert across.args[0] == "o1" and set(across.args[1:]) == {"o0", "o4"}
    related = {frozenset(a[1:]) for a in across.add if len(a) == 3}
    assert {frozenset({"o1", "o0"}), frozenset({"o1", "o4"})} <= related  # both at once
