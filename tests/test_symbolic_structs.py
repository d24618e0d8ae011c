"""symbolic/structs.py: atoms, lifted operators, ground steps and tasks, with known answers."""

import pytest

from drake_symplan.actions import Action
from drake_symplan.symbolic.structs import (
    Atom,
    LiftedOperator,
    Reposition,
    Step,
    Task,
    apply,
    other_outcomes,
    parse_step,
    reaches,
)

# ?o0 (a cube on the table) onto ?o1: ?o0 ends on ?o1.
STACK = LiftedOperator(19, "center", "right", 2, [("not_r0", 0, 1)], [("r0", 0, 1)],
                       [("not_r0", 0, 1)], 736, applicable=10, succeeded=8)
OPS = {STACK.name: STACK}


def test_atoms_are_tuples_with_names():
    a = Atom("r0", "o1", "o2")
    assert a == ("r0", "o1", "o2") and hash(a) == hash(("r0", "o1", "o2"))
    assert (a.predicate, a.args, a.key) == ("r0", ("o1", "o2"), ("r0", "o1", "o2"))
    assert Atom("not_p1", "o3").key == ("p1", "o3")
    assert Atom("r0", 1, 0).ground(["a", "b"]) == ("r0", "b", "a")
    assert Atom("r0", 0, 1).lifted() == ("r0", "?o0", "?o1")
    assert (a.text(), a.pddl()) == ("r0(o1, o2)", "(r0 o1 o2)")


def test_a_plan_step_is_parsed_once_into_its_operator_and_roles():
    step = parse_step("(pick_center_place_right_n736_op19 o3 o1)", OPS)
    assert isinstance(step, Step) and step.operator is STACK
    assert step.action == Action("o3", "center", "o1", "right")
    assert str(step) == "(pick_center_place_right_n736_op19 o3 o1)"
    assert parse_step("PICK_CENTER_PLACE_RIGHT_N736_OP19 o3 o1", OPS) == step
    move = parse_step("(reposition_left_center o1 o0)", OPS)
    assert move == Reposition(Action("o1", "left", "o0", "center"))
    assert str(move) == "(reposition_left_center o1 o0)"
    for bad in ("(pick_up_place_left_n5_op0 a b)", "(move a b)", "(pick_left_place_left_n5_op0 a)",
                "(pick_left_place_left_n5_op0 a b)",  # no such operator
                "(pick_center_place_right_n736_op19 a b c)"):  # too many arguments
        with pytest.raises(ValueError):
            parse_step(bad, OPS)


def test_a_step_applies_where_its_preconditions_hold():
    step = Step(STACK, ("a", "b"))
    state = frozenset({Atom("not_r0", "a", "b"), Atom("p0", "a")})
    assert step.applicable(state) and not step.applicable({Atom("p0", "a")})
    assert step.apply(state) == {Atom("r0", "a", "b"), Atom("p0", "a")}
    assert apply(state, [("x",)], [("p0", "a")]) == {("x",), ("not_r0", "a", "b")}
    assert reaches([step], state, {("r0", "a", "b")})
    assert not reaches([step, step], state, {("r0", "a", "b")})  # not applicable twice
    # A repositioning predicts no symbolic change and always applies.
    move = Reposition(Action("a", "center", "b", "left"))
    assert move.applicable(frozenset()) and move.apply(state) == state


def test_an_operator_reads_back_from_its_dict_and_keeps_its_reliability():
    again = LiftedOperator.from_dict(STACK.to_dict())
    assert again.name == STACK.name == "pick_center_place_right_n736_op19"
    assert (again.pre, again.add, again.delete) == (STACK.pre, STACK.add, STACK.delete)
    assert again.reliability == pytest.approx(0.8) and again.cost == STACK.cost == 3
    assert STACK.preconditions() == [("different", "?o0", "?o1"), ("not_r0", "?o0", "?o1")]


def test_a_task_restricted_to_some_objects_keeps_their_atoms():
    task = Task(("a", "b", "c"), frozenset({("p0", "a"), ("r0", "a", "c")}),
                frozenset({("r0", "a", "b")}))
    sub = task.restricted(["b", "a"])
    assert sub.objects == ("a", "b") and sub.init == {("p0", "a")}
    assert sub.goal == task.goal and not sub.solved


def test_atoms_and_operators_survive_pickling():
    import pickle

    again = pickle.loads(pickle.dumps(STACK))
    assert again.pre == STACK.pre and isinstance(again.pre[0], Atom)
    assert again.pre[0].key == ("r0", 0, 1)


def test_other_outcomes_are_the_branches_of_the_same_action_where_the_step_applies():
    # Four more operators of pick(center) place(right) besides STACK (80 %): one with
    # another effect (15 %), one with STACK's effect under other preconditions (a branch
    # already taken), one whose preconditions do not hold, one of other offsets.
    touches = LiftedOperator(20, "center", "right", 2, [("not_r0", 0, 1)],
                             [("touching2", 0)], [], 40, applicable=20, succeeded=3)
    same = LiftedOperator(21, "center", "right", 2, [], [("r0", 0, 1)], [("not_r0", 0, 1)],
                          30, applicable=10, succeeded=5)
    unmet = LiftedOperator(22, "center", "right", 2, [("p0", 0)], [("p1", 0)], [], 30,
                           applicable=10, succeeded=9)
    other = LiftedOperator(23, "left", "right", 2, [], [("p1", 0)], [], 30,
                           applicable=10, succeeded=9)
    ops = [STACK, touches, same, unmet, other]
    plan = [Step(STACK, ("a", "b")), Reposition(Action("a", "center", "b", "left")),
            Step(STACK, ("a", "b"))]
    out = other_outcomes(plan, {Atom("not_r0", "a", "b")}, ops)
    assert [[s.operator for s in row] for row in out] == [[touches], [], []]
    assert out[0][0].add == {("touching2", "a")} and out[0][0].operator.reliability == 0.15
