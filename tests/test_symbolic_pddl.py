"""Symbolic states as facts, PDDL writers, plan-step mapping and the plan checker."""

import numpy as np
import pytest
from pddl_reader import check_plan, read_domain, read_problem

from drake_symplan.symbolic.operators import LearnConfig, learn_operators
from drake_symplan.symbolic.pddl import domain_pddl, parse_sexpr, problem_pddl
from drake_symplan.symbolic.states import SymbolicState, bit_atoms, difference_facts
from drake_symplan.symbolic.structs import LiftedOperator
from drake_symplan.symbolic.synthetic import Row, dataset_from_rows


def two_cubes(on: bool) -> SymbolicState:
    """o0 centred on o1 (r0(o0, o1), r2(o1, o0)) or both on the table."""
    rel = np.zeros((3, 2, 2), bool)
    if on:
        rel[0, 0, 1] = rel[2, 1, 0] = True
    return SymbolicState(("o0", "o1"), np.zeros((2, 1), bool), rel)


def stack_domain():
    """Learned from rows: a cube onto a cube, centred, lands on it."""
    rows = [Row((0, 0), set(), (0, "center", 1, "center"), next_rel={(0, 0, 1), (2, 1, 0)})]
    ops = learn_operators(dataset_from_rows(rows), LearnConfig(min_count=1))
    return domain_pddl(ops.operators, 1, 3, n_transitions=1)


def test_state_facts_are_closed_world_and_positive():
    s = two_cubes(on=True)
    facts = s.facts()
    assert ("not_p0", "o0") in facts and ("r0", "o0", "o1") in facts
    assert ("not_r0", "o1", "o0") in facts and ("r2", "o1", "o0") in facts
    assert len(facts) == 2 * 1 + 2 * 3  # P per object, K per ordered pair, no self
    assert len(s.facts(self_relations=True)) == 2 + 4 * 3
    assert difference_facts(s.objects) == [("different", "o0", "o1"), ("different", "o1", "o0")]


def test_bits_make_one_atom_each_in_one_order_and_uncertain_bits_none():
    unary = np.array([[1, 0], [0, 1]], bool)
    rel = np.zeros((1, 2, 2), bool)
    rel[0, 1, 0] = True
    atoms, unknown = bit_atoms(unary, rel)  # over slots, no self-relations
    assert atoms == [("p0", 0), ("not_p1", 0), ("not_p0", 1), ("p1", 1),
                     ("not_r0", 0, 1), ("r0", 1, 0)] and unknown == []
    named = bit_atoms(unary, rel, names=("a", "b"), self_relations=True)[0]
    assert named[4:] == [("not_r0", "a", "a"), ("not_r0", "a", "b"), ("r0", "b", "a"),
                         ("not_r0", "b", "b")]
    # Uncertain bits make no atom but a key; only the objects and pairs asked for.
    atoms, unknown = bit_atoms(unary, rel, [1], [(1, 0)], unary_uncertain=unary,
                               relational_uncertain=~rel)
    assert atoms == [("not_p0", 1), ("r0", 1, 0)] and unknown == [("p1", 1)]
    assert SymbolicState(("a", "b"), unary, rel).facts() == bit_atoms(
        unary, rel, names=("a", "b"))[0]


def test_goal_relations_only_for_contacts():
    s = SymbolicState(("a", "b", "c"), np.zeros((3, 1)), np.zeros((3, 3, 3)))
    goal = s.goal_facts({("a", "b")})
    assert sorted({a[1:] for a in goal if len(a) == 3}) == [("a", "b"), ("b", "a")]
    assert len([a for a in goal if len(a) == 2]) == 3
    assert len(s.goal_facts(set())) == 3
    with pytest.raises(ValueError, match="unknown object"):
        s.goal_facts({("a", "z")})


def test_state_rejects_bad_names_and_shapes():
    with pytest.raises(ValueError, match="PDDL object name"):
        SymbolicState(("O1",), np.zeros((1, 1)), np.zeros((1, 1, 1)))
    with pytest.raises(ValueError, match="distinct"):
        SymbolicState(("a", "a"), np.zeros((2, 1)), np.zeros((1, 2, 2)))
    with pytest.raises(ValueError, match="relational"):
        SymbolicState(("a", "b"), np.zeros((2, 1)), np.zeros((1, 3, 3)))


def test_domain_is_positive_strips_with_roles_first():
    text = stack_domain()
    assert "(:requirements :strips :typing)" in text
    schemas = read_domain(text)
    (name, schema), = schemas.items()
    assert name == "pick_center_place_center_n1_op0"
    assert schema.params == ["?o0", "?o1"]
    assert ("different", "?o0", "?o1") in schema.pre
    assert sorted(schema.add) == [("r0", "?o0", "?o1"), ("r2", "?o1", "?o0")]
    assert sorted(schema.delete) == [("not_r0", "?o0", "?o1"), ("not_r2", "?o1", "?o0")]
    assert "(not (=" not in text and " - obj" in text


def test_problem_and_plan_check():
    domain = stack_domain()
    problem = problem_pddl(two_cubes(False), two_cubes(True), {("o0", "o1")}, name="p1")
    objects, init, goal = read_problem(problem)
    assert objects == ["o0", "o1"]
    assert ("different", "o0", "o1") in init and ("not_r0", "o0", "o1") in init
    assert ("r0", "o0", "o1") in goal and len(goal) == 2 + 2 * 3
    assert check_plan(domain, problem, ["(pick_center_place_center_n1_op0 o0 o1)"]) is None
    assert "goal not reached" in check_plan(domain, problem, [])
    assert "not applicable" in check_plan(
        domain, problem, ["(pick_center_place_center_n1_op0 o1 o0)"] * 2)
    assert "unknown action" in check_plan(domain, problem, ["(fly o0 o1)"])


def test_problem_needs_same_objects():
    other = SymbolicState(("o0", "o2"), np.zeros((2, 1)), np.zeros((3, 2, 2)))
    with pytest.raises(ValueError, match="different objects"):
        problem_pddl(two_cubes(False), other, set())


def test_sexpr_parser_reports_unbalanced_text():
    assert parse_sexpr("(define (x) ; comment )\n (y z))") == ["define", ["x"], ["y", "z"]]
    for bad in ("(define (x)", "(define))", "x y"):
        with pytest.raises(ValueError):
            parse_sexpr(bad)


def test_every_contact_degree_is_declared_when_operators_use_one():
    op = LiftedOperator(0, "center", "center", 2, (("touching0", 0), ("touching0", 1)),
                        (("touching1", 0), ("touching1", 1)),
                        (("touching0", 0), ("touching0", 1)), 10, 10, 10)
    text = domain_pddl([op], 1, 1)
    for n in range(4):  # touching3 appears in no operator, but a goal may hold it
        assert f"(touching{n} ?x0 - obj)" in text
    assert "touching" not in domain_pddl([], 1, 1)


def test_a_domain_for_two_objects_has_no_three_object_action_but_all_predicates():
    two = LiftedOperator(0, "center", "center", 2, (("p0", 0),), (("r0", 0, 1),), (), 5)
    three = LiftedOperator(1, "center", "center", 3, (("touching1", 2),),
                           (("r0", 0, 2),), (), 5)
    full = domain_pddl([two, three], 1, 1)
    small = domain_pddl([two, three], 1, 1, n_objects=2)
    assert set(read_domain(full)) == {two.name, three.name}
    assert set(read_domain(small)) == {two.name}
    assert "(touching1 ?x0 - obj)" in small  # a state may still hold it
    assert domain_pddl([two, three], 1, 1, n_objects=3) == full
