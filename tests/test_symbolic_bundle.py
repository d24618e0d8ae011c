"""The model bundle: written and loaded back, its problems and its step monitor, on a tiny
untrained model and hand-made operators and readings (known answers)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from drake_symplan.learning.checkpoint import save_checkpoint
from drake_symplan.learning.models import build_model
from drake_symplan.symbolic.bundle import BundleError, ModelBundle, Reading, write_bundle
from drake_symplan.symbolic.effect_operators import EFFECT, EffectOperator
from drake_symplan.symbolic.states import SymbolicState

# Stack ?o0 on ?o1 when both have p0 and touch nothing: adds r0(?o0, ?o1), not_r0(?o1, ?o0),
# and each now touches one object.
STACK = EffectOperator(
    0, "center", "left", 2, (("p0", 0), ("p0", 1), ("touching0", 0), ("touching0", 1)),
    (("not_r0", 1, 0), ("r0", 0, 1), ("touching1", 0), ("touching1", 1)),
    (("touching0", 0), ("touching0", 1)), 40, applicable=50, succeeded=40)


@pytest.fixture
def bundle(tmp_path) -> ModelBundle:
    torch.manual_seed(0)
    model = build_model("relational", state_dim=9, n_unary=1, n_relations=1)
    run = tmp_path / "run"
    run.mkdir()
    save_checkpoint(run / "best.pt", {"model": "relational", "model_config": model.config(),
                                      "model_state": model.state_dict(), "epoch": 1})
    write_bundle(tmp_path / "bundle", run, [STACK], EFFECT, {"learner": "effect"},
                 {"command": "test"})
    return ModelBundle.load(tmp_path / "bundle")


def reading(p0, on=(), contacts=(), uncertain=()):
    names = ("a", "b", "c")
    rel = np.zeros((1, 3, 3), bool)
    for x, y in on:
        rel[0, names.index(x), names.index(y)] = True
    unc = np.zeros((1, 3, 3), bool)
    for x, y in uncertain:
        unc[0, names.index(x), names.index(y)] = True
    return Reading(SymbolicState(names, np.array(p0, bool)[:, None], rel),
                   np.zeros((3, 1), bool), unc, set(contacts))


def test_a_bundle_round_trips_and_plans_with_costs(bundle):
    assert [op.name for op in bundle.operators] == [STACK.name]
    assert bundle.operators[0].reliability == 0.8
    assert "(increase (total-cost) 3)" in bundle.domain and "total-cost" not in \
        bundle.domain_strips
    start, goal = reading([1, 1, 0]), reading([1, 1, 0], on=[("a", "b")],
                                              contacts=[("a", "b")])
    text = bundle.problem(start, goal)
    assert "(r0 a b)" in text and "(not_r0 b a)" in text and "r0 a c" not in text
    result = bundle.plan(start, goal, "fd")
    assert result.solved and len(result.plan) == 1
    action = bundle.action_of(result.plan[0])
    assert (action.source, action.grasp, action.target, action.release) == (
        "a", "center", "b", "left")
    assert bundle.reliability(result.plan) == 0.8
    assert bundle.plan(start, goal, "pyperplan").solved


def test_goal_relations_only_between_objects_in_contact(bundle):
    goal = reading([1, 1, 1], on=[("a", "b"), ("b", "c")], contacts=[("a", "b")])
    atoms = bundle.goal_atoms(goal)
    assert ("r0", "a", "b") in atoms and not any(a[1:] == ("b", "c") for a in atoms)


def test_the_monitor_reports_what_did_not_come_true(bundle):
    step = f"({STACK.name} a b)"
    before = reading([1, 1, 0])
    done = reading([1, 1, 0], on=[("a", "b")], contacts=[("a", "b")])
    assert bundle.mismatches(done, step, before) == []
    fell = reading([1, 1, 0])  # a did not end on b: no contact, no relation atoms
    assert set(bundle.mismatches(fell, step, before)) == {
        ("not_r0", "b", "a"), ("r0", "a", "b"), ("touching1", "a"), ("touching1", "b"),
        ("touching0", "a"), ("touching0", "b")}
    unsure = reading([1, 1, 0], contacts=[("a", "b")], uncertain=[("a", "b"), ("b", "a")])
    assert bundle.mismatches(unsure, step, before) == []  # uncertain bits are no evidence


def test_a_missing_or_incomplete_bundle_is_one_clear_error(tmp_path, bundle):
    with pytest.raises(BundleError, match="does not exist"):
        ModelBundle.load(tmp_path / "nowhere")
    (bundle.path / "operators.json").unlink()
    with pytest.raises(BundleError, match="has no operators.json"):
        ModelBundle.load(bundle.path)


def test_plans_on_the_cost_domain_check_with_the_strips_reader(bundle):
    from drake_symplan.symbolic.pddl import check_plan

    start, goal = reading([1, 1, 0]), reading([1, 1, 0], on=[("a", "b")],
                                              contacts=[("a", "b")])
    text = bundle.problem(start, goal)
    plan = bundle.plan(start, goal, "fd").plan
    assert check_plan(bundle.domain, text, plan) is None
    assert check_plan(bundle.domain, text, []) is not None  # the goal does not hold yet


def test_planning_starts_with_the_objects_whose_goal_atoms_change(bundle, monkeypatch):
    from drake_symplan.planning import planners

    start = reading([1, 1, 1])
    goal = reading([1, 1, 1], on=[("a", "b")], contacts=[("a", "b")])
    # a and b take part in the missing r0(a, b); c neither changes nor touches them.
    assert bundle.focus(start, goal) == ("a", "b")
    # c touches b at the start: it is planned with too.
    assert bundle.focus(reading([1, 1, 1], contacts=[("b", "c")]), goal) == ("a", "b", "c")
    assert bundle.focus(goal, goal) == ()
    text = bundle.problem(start, goal, objects=("a", "b"))
    assert "(:objects a b - obj)" in text and " c" not in text.split(":init")[1]
    problems = []
    real = planners.plan_pddl

    def spy(domain, problem, *args, **kwargs):
        problems.append(problem)
        return real(domain, problem, *args, **kwargs)

    monkeypatch.setattr(planners, "plan_pddl", spy)
    result = bundle.plan(start, goal, "fd")
    assert result.solved and len(result.plan) == 1 and len(problems) == 1
    assert "(:objects a b - obj)" in problems[0]
    # Already there: the empty plan, without a planner call.
    assert bundle.plan(goal, goal, "fd").plan == [] and len(problems) == 1
    # a and b lack p0, which no operator adds:
    # unsolvable on the focus, then on all objects before that is the answer.
    stuck = reading([0, 0, 1])
    assert bundle.plan(stuck, goal, "fd").status == "unsolvable" and len(problems) == 3
    assert "(:objects a b c - obj)" in problems[2]
