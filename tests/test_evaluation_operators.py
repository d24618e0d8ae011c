"""The symbolic-level evaluation on hand-made scene symbols: problems from chains of steps,
trivial goals left out, goal relations only between objects in contact."""

from __future__ import annotations

import numpy as np

from drake_symplan.datasets import SceneSymbols
from drake_symplan.evaluation import operators as operator_eval
from drake_symplan.evaluation.operators import EvalConfig, heldout_problems, solve_problems
from drake_symplan.planning.planners import PlanResult
from drake_symplan.symbolic.effect_operators import EFFECT
from drake_symplan.symbolic.structs import LiftedOperator


def scenes(unary_steps, contacts_steps, episode=None, chain=None):
    """One scene row per step: unary [T+1 states][M, 1]; the relation r0 is 'a on b'."""
    t = len(unary_steps) - 1
    m = len(unary_steps[0])
    u = np.array(unary_steps, np.uint8)[..., None]
    rel = np.zeros((t + 1, 1, m, m), np.uint8)
    rel[:, 0, 0, 1] = 1  # r0(o0, o1) is read everywhere, meaningful only in contact
    c = np.array(contacts_steps, bool)
    z = np.zeros_like
    return SceneSymbols(
        unary=u[:-1], relational=rel[:-1], unary_uncertain=z(u[:-1], bool),
        relational_uncertain=z(rel[:-1], bool), next_unary=u[1:], next_relational=rel[1:],
        next_unary_uncertain=z(u[1:], bool), next_relational_uncertain=z(rel[1:], bool),
        mask=np.ones((t, m), bool), contacts=c[:-1], next_contacts=c[1:],
        episode=np.zeros(t, np.int64) if episode is None else np.array(episode),
        step=np.arange(t), chain=np.zeros(t, np.int64) if chain is None else np.array(chain))


APART = [[False, False], [False, False]]
TOUCH = [[False, True], [True, False]]


def test_problems_from_chains_skip_trivial_goals_and_use_contact_relations():
    # Step 0 changes nothing; step 1 brings o0 onto o1 (contact); step 2 flips o1's bit.
    sc = scenes([[1, 1], [1, 1], [1, 1], [1, 0]], [APART, APART, TOUCH, TOUCH])
    problems = heldout_problems(sc, EFFECT, EvalConfig(ks=(1, 2, 3)))
    by_k = {}
    for p in problems:
        by_k.setdefault(p.k, []).append(p)
    assert [len(by_k[k]) for k in (1, 2, 3)] == [2, 2, 1]  # k=1 from step 0 is trivial
    first = by_k[1][0]
    assert ("r0", "o0", "o1") in first.task.goal and ("not_r0", "o1", "o0") in first.task.goal
    assert not any(a[0].endswith("r0") for a in first.task.init)  # apart: no relation atoms
    assert ("p0", "o0") in by_k[3][0].task.goal and ("not_p0", "o1") in by_k[3][0].task.goal


def test_problems_never_span_two_chains():
    sc = scenes([[1, 1], [1, 1], [1, 0]], [APART, TOUCH, TOUCH], chain=[0, 1])
    problems = heldout_problems(sc, EFFECT, EvalConfig(ks=(1, 2)))
    assert [p.k for p in problems] == [1, 1]


def test_each_planner_call_gets_cpu_seconds_with_a_wall_clock_cap(monkeypatch):
    # A busy host must give the planner the same work as a quiet one: the budget is CPU
    # seconds (--timeout), wall-clock time only its cap (three times that).
    calls = []

    def plan_task(operators, domain, task, planner, timeout, cpu_seconds=None):
        calls.append((planner, timeout, cpu_seconds))
        return PlanResult("timeout", planner=planner)

    monkeypatch.setattr(operator_eval, "plan_task", plan_task)
    sc = scenes([[1, 1], [1, 1], [1, 0]], [APART, TOUCH, TOUCH])
    config = EvalConfig(ks=(1,), timeout=2.0, workers=1)
    results = solve_problems([], 1, 1, heldout_problems(sc, EFFECT, config), config)
    assert [r["status"] for r in results] == ["timeout", "timeout"]
    assert calls == [("fd", 6.0, 2.0), ("fd", 6.0, 2.0)]


def test_a_problem_is_planned_without_operators_needing_more_objects_than_it_has(monkeypatch):
    # Parameters must differ, so a 3-parameter operator never applies with 2 objects; the
    # planner's translator would still read it.
    domains = []

    def plan_task(operators, domain, task, planner, timeout, cpu_seconds=None):
        domains.append(domain())
        return PlanResult("timeout", planner=planner)

    monkeypatch.setattr(operator_eval, "plan_task", plan_task)
    two = LiftedOperator(0, "center", "center", 2, (("p0", 0),), (("r0", 0, 1),), (), 5)
    three = LiftedOperator(1, "center", "center", 3, (("p0", 2),), (("r0", 0, 2),), (), 5)
    sc = scenes([[1, 1], [1, 1], [1, 0]], [APART, TOUCH, TOUCH])
    config = EvalConfig(ks=(1,), workers=1)
    solve_problems([two, three], 1, 1, heldout_problems(sc, EFFECT, config), config)
    assert len(domains) == 2
    assert all(two.name in d and three.name not in d for d in domains)
