"""Grounding tasks here for Fast Downward's search: the reachable actions on a tiny domain,
proofs without search, and the same plans and costs as FD's own translator on learned
domains."""

import numpy as np
import pytest
from pddl_reader import check_plan

from drake_symplan.abstraction import abstraction
from drake_symplan.abstraction.abstraction import plan_task, problem_text
from drake_symplan.planning import grounding
from drake_symplan.planning.grounding import fast_downward_task, ground, sas_text
from drake_symplan.planning.planners import plan_pddl, search_binary
from drake_symplan.symbolic import synthetic
from drake_symplan.symbolic.operators import LearnConfig, learn_operators
from drake_symplan.symbolic.pddl import domain_pddl
from drake_symplan.symbolic.structs import Atom, Goal, LiftedOperator, Task, parse_step

needs_search = pytest.mark.skipif(search_binary() is None,
                                  reason="up-fast-downward has no search binary here")

# put: a box that is free (p0) goes onto another (r0) and is no longer free.
PUT = LiftedOperator(0, "center", "center", 2, (("p0", 0),), (("r0", 0, 1),), (("p0", 0),),
                     9, applicable=10, succeeded=9)
# mark: whatever has a box on it becomes p1.
MARK = LiftedOperator(1, "center", "left", 2, (("r0", 0, 1),), (("p1", 1),), (), 5,
                      applicable=5, succeeded=5)
# three: needs three distinct boxes.
THREE = LiftedOperator(2, "left", "left", 3, (("p0", 0),), (("p1", 2),), (), 4)


def names(task):
    return sorted(a.name for a in task.actions)


def test_ground_keeps_the_reachable_actions_on_distinct_objects():
    task = Task(("a", "b", "c"), frozenset({Atom("p0", "a"), Atom("p1", "a")}),
                frozenset({Atom("p1", "b")}))
    g = ground([PUT, MARK, THREE], task)
    put, mark, three = PUT.name, MARK.name, THREE.name
    assert names(g) == sorted([f"{put} a b", f"{put} a c", f"{mark} a b", f"{mark} a c",
                               f"{three} a b c", f"{three} a c b"])
    # p1(a) holds and nothing changes it: static, so it is no variable.
    assert set(g.variables) == {Atom("p0", "a"), Atom("r0", "a", "b"), Atom("r0", "a", "c"),
                                Atom("p1", "b"), Atom("p1", "c")}
    assert g.init == {Atom("p0", "a")} and g.goal == {Atom("p1", "b")} and not g.unreachable
    # Two boxes: nothing binds the three-parameter operator.
    two = Task(("a", "b"), frozenset({Atom("p0", "a")}), frozenset({Atom("p1", "b")}))
    assert names(ground([PUT, MARK, THREE], two)) == sorted([f"{put} a b", f"{mark} a b"])



def test_grounding_past_the_plans_budget_is_a_timeout_and_is_not_kept():
    # sixteen boxes ground 170,000 actions in 15 to 30 s: the budget counts that time
    task = Task(("a", "b", "c", "d"), frozenset({Atom("p0", "a")}),
                frozenset({Atom("p1", "b")}))
    found = fast_downward_task([PUT, MARK, THREE], task, wall_seconds=1.0, cpu_seconds=0.0)
    assert found.status == "timeout" and found.message == "grounding out of time"
    with pytest.raises(grounding.OutOfTime):
        ground([PUT, MARK, THREE], task, out_of_time=lambda: True)
    # grounded anew, in full: 12 reachable, less THREE's second way to each p1 (the
    # same precondition and effect: dominated)
    assert len(ground([PUT, MARK, THREE], task).actions) == 9


def test_a_move_costs_a_carry_per_box_the_preconditions_relate_to_its_source():
    # a block laid across two supports names the second (related to the target) and
    # carries nothing; priced as a carry it lost to a place beside each support in turn
    span = LiftedOperator(3, "right", "right", 3, (("p0", 0), ("r0", 1, 2)),
                          (("r1", 0, 2),), (), 4)
    carry = LiftedOperator(4, "center", "center", 3, (("p0", 0), ("r0", 2, 0)),
                           (("r1", 0, 1),), (), 4)
    unrelated = LiftedOperator(5, "center", "left", 3, (("p0", 0), ("not_r0", 2, 0)),
                               (("r2", 0, 1),), (), 4)
    assert (span.carried, carry.carried, unrelated.carried) == (0, 1, 0)
    task = Task(("a", "b", "c"), frozenset({Atom("p0", "a"), Atom("r0", "b", "c"),
                                            Atom("r0", "c", "a"), Atom("not_r0", "c", "a")}),
                frozenset({Atom("r1", "a", "c")}))
    costs = {a.name.split()[0]: a.cost for a in ground([span, carry, unrelated], task,
                                                        carry_cost=5).actions}
    assert costs == {span.name: span.cost, carry.name: carry.cost + 5,
                     unrelated.name: unrelated.cost}


def test_a_task_grounded_again_is_priced_by_its_own_penalties():
    # The reachable part is kept between calls (a plan's skeletons ground one task twice);
    # each call's penalties price it anew, a longer key only the actions that name it all.
    task = Task(("a", "b", "c"), frozenset({Atom("p0", "a")}), frozenset({Atom("p1", "b")}))

    def costs(penalties):
        return {a.name: a.cost for a in ground([PUT, MARK, THREE], task, penalties).actions}

    plain = costs(None)
    priced = costs({("a", "b"): 1000, ("a", "c", "b"): 7})
    assert priced[f"{PUT.name} a b"] == plain[f"{PUT.name} a b"] + 1000
    assert priced[f"{THREE.name} a c b"] == plain[f"{THREE.name} a c b"] + 7
    assert priced[f"{PUT.name} a c"] == plain[f"{PUT.name} a c"]
    assert costs(None) == plain


def test_the_sas_text_has_one_binary_variable_per_atom_and_the_actions_costs():
    task = Task(("a", "b"), frozenset({Atom("p0", "a")}), frozenset({Atom("p1", "b")}))
    text = sas_text(ground([PUT, MARK], task))
    assert text.count("begin_variable") == 3 and text.count("begin_operator") == 2
    assert f"begin_operator\n{PUT.name} a b\n0\n2\n" in text  # no prevail, two effects
    assert f"\n{PUT.cost}\nend_operator" in text and PUT.cost != MARK.cost


def test_an_unreachable_goal_is_unsolvable_without_a_search(monkeypatch):
    monkeypatch.setattr(grounding, "fast_downward_sas", lambda *a, **k: pytest.fail("searched"))
    task = Task(("a", "b"), frozenset({Atom("p0", "a")}), frozenset({Atom("p1", "a")}))
    result = fast_downward_task([PUT, MARK], task)
    assert result.status == "unsolvable" and "p1(a)" in result.message
    held = Task(("a", "b"), frozenset({Atom("p0", "a"), Atom("p1", "a")}),
                frozenset({Atom("p1", "a")}))
    assert fast_downward_task([PUT, MARK], held).status == "solved"


@needs_search
def test_fast_downward_on_the_grounded_task_finds_the_two_step_plan():
    task = Task(("a", "b", "c"), frozenset({Atom("p0", "a")}),
                frozenset({Atom("p1", "c"), Atom("r0", "a", "c")}))
    result = fast_downward_task([PUT, MARK], task)
    assert result.solved, result.message
    assert result.plan == [f"({PUT.name} a c)", f"({MARK.name} a c)"]


@needs_search
def test_penalties_make_the_planner_move_other_boxes():
    # Two plans of equal cost: put a or b on c, then mark c.
    task = Task(("a", "b", "c"), frozenset({Atom("p0", "a"), Atom("p0", "b")}),
                frozenset({Atom("p1", "c")}))
    first = fast_downward_task([PUT, MARK], task)
    source = first.plan[0].split()[1]
    other = {"a": "b", "b": "a"}[source]
    assert first.plan == [f"({PUT.name} {source} c)", f"({MARK.name} {source} c)"]
    again = fast_downward_task([PUT, MARK], task, penalties={(source, "c"): 1000})
    assert again.plan == [f"({PUT.name} {other} c)", f"({MARK.name} {other} c)"]
    # A key that names more arguments (a carry's rider) only prices actions that name them.
    assert fast_downward_task([PUT, MARK], task, penalties={(source, "c", other): 1000}
                              ).plan == first.plan
    # Where every plan moves the pair, the penalty costs but the plan stays.
    one = Task(("a", "c"), frozenset({Atom("p0", "a")}), frozenset({Atom("p1", "c")}))
    assert fast_downward_task([PUT, MARK], one, penalties={("a", "c"): 1000}).solved


@pytest.fixture(scope="module")
def learned():
    data = synthetic.random_transitions(20000, seed=0)
    return learn_operators(data, LearnConfig(min_count=20)).operators


@needs_search
def test_grounded_and_translated_tasks_get_plans_of_the_same_cost(learned):
    domain = domain_pddl(learned, synthetic.N_UNARY, synthetic.N_RELATIONS, costs=True)
    by_name = {op.name: op for op in learned}
    rng = np.random.default_rng(3)
    solved = 0
    for _ in range(15):
        start, goal, contacts = synthetic.random_problem(4, int(rng.integers(2, 5)), rng)
        task = Task(start.objects, frozenset(start.facts()),
                    frozenset(goal.goal_facts(contacts)))
        ours = plan_task(learned, lambda: domain, task)
        theirs = plan_pddl(domain, problem_text(task, costs=True), "fd")
        assert ours.status == theirs.status, (ours, theirs)
        costs = [sum(parse_step(s, by_name).operator.cost for s in r.plan)
                 for r in (ours, theirs)]
        assert costs[0] == costs[1]
        if ours.solved:
            assert check_plan(domain, problem_text(task, costs=True), ours.plan) is None
        solved += ours.solved
    assert solved >= 10


def test_without_a_search_binary_the_task_goes_to_the_planner_as_pddl(learned, monkeypatch):
    monkeypatch.setattr(abstraction, "search_binary", lambda: None)
    asked = []
    domain = domain_pddl(learned, synthetic.N_UNARY, synthetic.N_RELATIONS, costs=True)
    start, goal, contacts = synthetic.random_problem(3, 2, np.random.default_rng(4))
    task = Task(start.objects, frozenset(start.facts()), frozenset(goal.goal_facts(contacts)))
    result = plan_task(learned, lambda: asked.append(1) or domain, task, "fd")
    assert asked == [1] and result.status in ("solved", "unsolvable")


@needs_search
def test_of_plans_of_equal_moves_a_choices_first_set_is_planned_a_shorter_plan_wins():
    # a pair read as the example reads it (a choice's first set) against a kept pattern:
    # put a or b on c, one move each: the first set's; a plan a move shorter (put, no
    # mark) to the second set beats the first's two
    init = frozenset({Atom("p0", "a"), Atom("p0", "b")})
    for first, other in (("a", "b"), ("b", "a")):
        task = Task(("a", "b", "c"), init, Goal((), [(("c",), [
            {Atom("r0", first, "c")}, {Atom("r0", other, "c")}])]))
        assert fast_downward_task([PUT, MARK], task).plan == [f"({PUT.name} {first} c)"]
    task = Task(("a", "b", "c"), init, Goal((), [(("b", "c"), [
        {Atom("p1", "b"), Atom("r0", "a", "b")}, {Atom("r0", "b", "c")}])]))
    assert fast_downward_task([PUT, MARK], task).plan == [f"({PUT.name} b c)"]


@needs_search
def test_a_goal_with_choices_is_reached_by_any_of_its_sets():
    # b on c may read r0 (put) or p1 under it (mark after put on c): either set will do,
    # and no action follows the set it ends at (the atoms hold at the plan's end)
    task = Task(("a", "b", "c"), frozenset({Atom("p0", "a"), Atom("p0", "b")}),
                Goal({Atom("p0", "a")}, [(("b", "c"), [{Atom("p1", "b")},
                                                       {Atom("r0", "b", "c")}])]))
    found = fast_downward_task([PUT, MARK, THREE], task)
    assert found.plan == [f"({PUT.name} b c)"]  # one step: the second set; no choice step
    assert not ground([PUT, MARK], task).solved()
    # the first set alone takes two steps (a onto b, then mark b)
    only = Task(task.objects, task.init, Goal((), [(("b", "c"), [{Atom("p1", "b")}])]))
    assert len(fast_downward_task([PUT, MARK], only).plan) == 2
    # a choice no set of which can hold: unsolvable without search
    never = Task(task.objects, task.init, Goal((), [(("b", "c"), [{Atom("r0", "c", "b"),
                                                                   Atom("p1", "c")}])]))
    assert fast_downward_task([PUT], never).status == "unsolvable"
    # held already: solved without a step
    held = Task(task.objects, task.init | {Atom("r0", "b", "c")}, task.goal)
    found = fast_downward_task([PUT, MARK, THREE], held)
    assert found.solved and found.plan == []


def test_an_action_another_dominates_is_left_out():
    # the same effects from fewer preconditions at no higher cost: a cost-optimal plan
    # never needs the other (learned operators with other offsets share effects)
    from drake_symplan.planning.grounding import GroundAction, undominated

    x, y, z, w = (Atom("p0", n) for n in "xyzw")
    a = GroundAction("a", frozenset({x}), frozenset({y}), frozenset(), 2)
    b = GroundAction("b", frozenset({x, z}), frozenset({y}), frozenset(), 3)
    c = GroundAction("c", frozenset({x, z}), frozenset({y}), frozenset(), 1)
    d = GroundAction("d", frozenset({x}), frozenset({y}), frozenset(), 2)
    e = GroundAction("e", frozenset({x}), frozenset({y}), frozenset({w}), 9)
    assert [act.name for act in undominated([a, b, c, d, e])] == ["a", "c", "e"]
