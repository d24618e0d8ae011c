"""The model bundle and its abstraction: written and loaded back, the tasks and plans it
makes and its step monitor, on a tiny untrained model and hand-made operators and readings
(known answers)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from drake_symplan.abstraction import abstraction as abstraction_module
from drake_symplan.abstraction.abstraction import Abstraction, Reading, problem_text, reliability
from drake_symplan.learning.checkpoint import save_checkpoint
from drake_symplan.learning.models import build_model
from drake_symplan.symbolic.bundle import (
    OPERATORS_VERSION,
    BundleError,
    ModelBundle,
    write_bundle,
)
from drake_symplan.symbolic.effect_operators import EFFECT
from drake_symplan.symbolic.states import SymbolicState
from drake_symplan.symbolic.structs import LiftedOperator, Step

# Stack ?o0 on ?o1 when both have p0 and touch nothing: adds r0(?o0, ?o1), not_r0(?o1, ?o0),
# and each now touches one object.
STACK = LiftedOperator(
    0, "center", "left", 2, (("p0", 0), ("p0", 1), ("touching0", 0), ("touching0", 1)),
    (("not_r0", 1, 0), ("r0", 0, 1), ("touching1", 0), ("touching1", 1)),
    (("touching0", 0), ("touching0", 1)), 40, applicable=50, succeeded=40)


@pytest.fixture
def bundle(tmp_path) -> Abstraction:
    torch.manual_seed(0)
    model = build_model("relational", state_dim=9, n_unary=1, n_relations=1)
    run = tmp_path / "run"
    run.mkdir()
    save_checkpoint(run / "best.pt", {"model": "relational", "model_config": model.config(),
                                      "model_state": model.state_dict(), "epoch": 1})
    write_bundle(tmp_path / "bundle", run, [STACK], EFFECT, {"learner": "effect"},
                 {"command": "test"})
    return Abstraction(ModelBundle.load(tmp_path / "bundle"))


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
    data = bundle.bundle
    assert [op.name for op in data.operators] == [STACK.name]
    assert data.operators[0].reliability == 0.8
    assert "(increase (total-cost) 3)" in data.domain and "total-cost" not in \
        data.domain_strips
    written = json.loads((data.path / "operators.json").read_text())
    assert written["version"] == OPERATORS_VERSION and written["learner"] == "effect"
    start, goal = reading([1, 1, 0]), reading([1, 1, 0], on=[("a", "b")],
                                              contacts=[("a", "b")])
    text = problem_text(bundle.task(start, goal), costs=True)
    assert "(r0 a b)" in text and "(not_r0 b a)" in text and "r0 a c" not in text
    result = bundle.plan(start, goal, "fd")
    assert result.solved and len(result.steps) == 1
    step = result.steps[0]
    assert isinstance(step, Step) and step.operator.name == STACK.name
    action = step.action
    assert (action.source, action.grasp, action.target, action.release) == (
        "a", "center", "b", "left")
    assert reliability(result.steps) == 0.8
    assert bundle.plan(start, goal, "pyperplan").solved


def test_goal_relations_only_between_objects_in_contact(bundle):
    goal = reading([1, 1, 1], on=[("a", "b"), ("b", "c")], contacts=[("a", "b")])
    atoms = bundle.goal_atoms(goal)
    assert ("r0", "a", "b") in atoms and not any(a[1:] == ("b", "c") for a in atoms)


def test_the_monitor_reports_what_did_not_come_true(bundle):
    step = bundle.step(f"({STACK.name} a b)")
    done = reading([1, 1, 0], on=[("a", "b")], contacts=[("a", "b")])
    assert bundle.mismatches(done, step) == []
    fell = reading([1, 1, 0])  # a did not end on b: no contact, no relation atoms
    assert set(bundle.mismatches(fell, step)) == {
        ("not_r0", "b", "a"), ("r0", "a", "b"), ("touching1", "a"), ("touching1", "b"),
        ("touching0", "a"), ("touching0", "b")}
    unsure = reading([1, 1, 0], contacts=[("a", "b")], uncertain=[("a", "b"), ("b", "a")])
    assert bundle.mismatches(unsure, step) == []  # uncertain bits are no evidence


def test_a_missing_or_incomplete_bundle_is_one_clear_error(tmp_path, bundle):
    with pytest.raises(BundleError, match="does not exist"):
        ModelBundle.load(tmp_path / "nowhere")
    path = bundle.bundle.path / "operators.json"
    data = json.loads(path.read_text())
    path.write_text(json.dumps({**data, "version": 99}))
    with pytest.raises(BundleError, match="version 99"):
        ModelBundle.load(path.parent)
    path.unlink()
    with pytest.raises(BundleError, match="has no operators.json"):
        ModelBundle.load(path.parent)


def test_plans_on_the_cost_domain_check_with_the_strips_reader(bundle):
    from pddl_reader import check_plan

    start, goal = reading([1, 1, 0]), reading([1, 1, 0], on=[("a", "b")],
                                              contacts=[("a", "b")])
    text = problem_text(bundle.task(start, goal), costs=True)
    plan = [str(s) for s in bundle.plan(start, goal, "fd").steps]
    assert check_plan(bundle.bundle.domain, text, plan) is None
    assert check_plan(bundle.bundle.domain, text, []) is not None  # the goal does not hold


def test_planning_starts_with_the_objects_whose_goal_atoms_change(bundle, monkeypatch):
    start = reading([1, 1, 1])
    goal = reading([1, 1, 1], on=[("a", "b")], contacts=[("a", "b")])

    def focus(s, g):
        return bundle.focus(bundle.task(s, g), s, g)

    # a and b take part in the missing r0(a, b); c neither changes nor touches them.
    assert focus(start, goal) == ("a", "b")
    # c touches b at the start: it is planned with too.
    assert focus(reading([1, 1, 1], contacts=[("b", "c")]), goal) == ("a", "b", "c")
    assert focus(goal, goal) == ()
    text = problem_text(bundle.task(start, goal).restricted(("a", "b")), costs=True)
    assert "(:objects a b - obj)" in text and " c" not in text.split(":init")[1]
    tasks = []
    real = abstraction_module.fast_downward_task

    def spy(operators, task, *args, **kwargs):
        tasks.append(task)
        return real(operators, task, *args, **kwargs)

    monkeypatch.setattr(abstraction_module, "fast_downward_task", spy)
    result = bundle.plan(start, goal, "fd")
    assert result.solved and len(result.steps) == 1 and len(tasks) == 1
    assert tasks[0].objects == ("a", "b")
    # Already there: the empty plan, without a planner call.
    assert bundle.plan(goal, goal, "fd").steps == [] and len(tasks) == 1
    # a and b lack p0, which no operator adds:
    # unsolvable on the focus, then on all objects before that is the answer.
    stuck = reading([0, 0, 1])
    assert bundle.plan(stuck, goal, "fd").status == "unsolvable" and len(tasks) == 3
    assert tasks[2].objects == ("a", "b", "c")


def test_a_bundle_written_before_the_version_field_still_loads(bundle):
    path = bundle.bundle.path / "operators.json"
    data = json.loads(path.read_text())
    for key in ("format", "version"):
        del data[key]
    for op in data["operators"]:  # version 1 had no outcomes, examples or cost_scale
        for key in ("outcomes", "effect_count", "example", "example_slots", "cost_scale"):
            del op[key]
    path.write_text(json.dumps(data))
    again = ModelBundle.load(path.parent)
    assert [op.to_dict() for op in again.operators] == [
        op.to_dict() for op in bundle.bundle.operators]


def test_a_continuous_model_is_added_to_a_bundle_and_loaded_beside_its_symbol_model(bundle,
                                                                                    capsys):
    from drake_symplan.cli import main as cli_main

    path = bundle.bundle.path
    assert bundle.bundle.continuous == [bundle.bundle.model]  # none: the symbol model rolls
    run = path.parent / "run"
    assert cli_main.main(["bundle", "--continuous", str(run), "--out", str(path)]) == 0
    again = ModelBundle.load(path)
    assert (path / "continuous.pt").is_file() and len(again.continuous) == 1
    assert again.continuous[0] is not again.model
    assert type(again.continuous[0]) is type(again.model)
    # Several runs: an ensemble's members in one file, each with the run's weights.
    assert cli_main.main(["bundle", "--continuous", str(run), str(run), "--out",
                          str(path)]) == 0
    members = ModelBundle.load(path).continuous
    assert len(members) == 2
    for member in members:
        for key, value in member.state_dict().items():
            assert torch.equal(value, again.continuous[0].state_dict()[key])
    assert cli_main.main(["bundle", "--out", str(path)]) == 2  # neither --run nor --continuous
    assert "give --run (or --symbols) and --data" in capsys.readouterr().err


def stacking_data(path, n: int = 12):
    """A data set of `n` transitions with whole scenes: cube a, on the table 10 cm from cube
    b, is put on b; a long block c lies apart, in the scene and in no transition."""
    from drake_symplan.actions import Action, encode_action
    from drake_symplan.datasets import TransitionArrays
    from drake_symplan.features import object_features
    from drake_symplan.shards import write_manifest, write_shard

    def features(*centres):
        out = np.zeros((n, 8, 9), np.float32)
        for slot, (kind, x, y, z) in enumerate(centres):
            for t in range(n):
                out[t, slot] = object_features(kind, np.array([x + 0.01 * t, y, z]),
                                               np.eye(3))
        return out

    c = ("long", 0.5, 0.3, 0.025)
    before = features(("cube", 0.5, 0.0, 0.025), ("cube", 0.6, 0.0, 0.025), c)
    after = features(("cube", 0.6, 0.0, 0.075), ("cube", 0.6, 0.0, 0.025), c)
    scene_mask = np.zeros((n, 8), bool)
    scene_mask[:, :3] = True
    touching = np.zeros((n, 8, 8), bool)
    touching[:, 0, 1] = touching[:, 1, 0] = True
    action = np.repeat(encode_action(Action("a", "center", "b", "center"), ["a", "b"])[None],
                       n, axis=0)
    arrays = TransitionArrays(before[:, :2], action, np.zeros((n, 2, 6), np.float32),
                              np.ones((n, 2), bool), np.arange(n), after[:, :2])
    write_manifest(path, {"config": {"relevance_radius": 0.006}})
    write_shard(path, 0, arrays, extra={
        "scene_state": before, "scene_next_state": after, "scene_mask": scene_mask,
        "scene_contacts": np.zeros((n, 8, 8), bool), "scene_next_contacts": touching,
        "scene_slots": np.tile(np.array([0, 1], np.int8), (n, 1)),
        "chain": np.zeros(n, np.int16), "step": np.zeros(n, np.int32)})
    return path


def test_a_bundle_of_the_handmade_symbols_is_made_from_a_data_set_without_a_run(
        tmp_path, capsys, monkeypatch):
    from drake_symplan.cli import main as cli_main
    from drake_symplan.learning.handmade import HandmadeSymbols

    data, out = stacking_data(tmp_path / "data"), tmp_path / "handmade"
    argv = ["bundle", "--symbols", "handmade", "--data", str(data), "--out", str(out),
            "--min-count", "10", "--json"]
    monkeypatch.setattr("sys.argv", ["symplan", *argv])
    assert cli_main.main(argv) == 0
    assert json.loads(capsys.readouterr().out)["operators"] == 1
    bundle = ModelBundle.load(out)
    assert isinstance(bundle.model, HandmadeSymbols)
    assert (bundle.n_unary, bundle.n_relations) == (1, 1)
    [op] = bundle.operators
    # Two cubes (not long) touching nothing: the source ends on the target, both touch one.
    assert op.count == 12 and op.reliability == 1.0
    assert set(op.pre) == {("not_p0", 0), ("not_p0", 1), ("touching0", 0), ("touching0", 1)}
    assert set(op.add) == {("r0", 0, 1), ("not_r0", 1, 0), ("touching1", 0), ("touching1", 1)}
    provenance = json.loads((out / "provenance.json").read_text())
    assert provenance["symbols"] == "handmade" and provenance["rule"]["on_dz"] == 0.03
    assert provenance["command"] == "symplan " + " ".join(argv)
    assert "run" not in provenance
    assert cli_main.main(["bundle", "--symbols", "handmade", "--run", str(tmp_path),
                          "--data", str(data), "--out", str(out)]) == 2
    assert "not both" in capsys.readouterr().err


def test_a_bundle_is_made_again_from_a_bundles_model(bundle, tmp_path):
    # `symplan bundle --run BUNDLE`: operators learned again on another bundle's symbols
    again = write_bundle(tmp_path / "again", tmp_path / "bundle", [STACK], EFFECT,
                         {"learner": "effect"}, {"command": "test"})
    first = bundle.bundle.model.state_dict()
    second = ModelBundle.load(again).model.state_dict()
    assert first.keys() == second.keys()
    assert all(torch.equal(first[k], second[k]) for k in first)


def test_extending_a_bundle_keeps_its_operators_and_asks_for_its_own_model(
        bundle, tmp_path, capsys, monkeypatch):
    from drake_symplan.cli import main as cli_main

    data, out = stacking_data(tmp_path / "data"), tmp_path / "extended"
    base = tmp_path / "bundle"
    argv = ["bundle", "--run", str(base), "--data", str(data), "--out", str(out),
            "--extend", str(base), "--json"]
    monkeypatch.setattr("sys.argv", ["symplan", *argv])
    assert cli_main.main(argv) == 0
    # the stacking data teach no operator that spans two boxes: the bundle's own, as it is
    assert json.loads(capsys.readouterr().out)["operators"] == 1
    extended = ModelBundle.load(out)
    assert [op.to_dict() for op in extended.operators] == [STACK.to_dict()]
    assert json.loads((out / "provenance.json").read_text())["extends"] == str(base)
    other = ["bundle", "--run", str(tmp_path / "run"), "--data", str(data), "--out",
             str(tmp_path / "other"), "--extend", str(base)]
    assert cli_main.main(other) == 2
    assert "model.pt is not --run's model" in capsys.readouterr().err
    assert not (tmp_path / "other").exists()
