"""The closed loop on a fake world (no simulator, no learned model): naming perceived boxes
after the scene file, the monitor's replanning, goal contacts, the check and its JSON.

FakeBackend moves a picked box onto the target's top and perceives exact boxes;
OracleAbstraction reads "a rests on b" from the features and plans with a one-action
domain (Fast Downward or pyperplan run for real)."""

from __future__ import annotations

import contextlib

import numpy as np
import pytest

from drake_symplan.abstraction.abstraction import Abstraction, Plan, Reading
from drake_symplan.actions import Action
from drake_symplan.agent import beliefs
from drake_symplan.agent.config import SolveConfig
from drake_symplan.agent.solve import REFUSALS_PER_OBJECT, Agent, SolveResult
from drake_symplan.boxes import CONTACT_TOLERANCE
from drake_symplan.datasets import ObjectState
from drake_symplan.features import object_features
from drake_symplan.perception.perceive import PerceivedObject, PerceivedScene
from drake_symplan.robot.backends import Execution
from drake_symplan.symbolic.states import SymbolicState
from drake_symplan.symbolic.structs import Atom, LiftedOperator, PlanningOperators
from drake_symplan.world.scenes import ObjectSpec, Scene

DOMAIN = """(define (domain symplan) (:requirements :strips :typing :action-costs) (:types obj)
 (:predicates (on ?x ?y - obj) (free ?x - obj) (different ?x ?y - obj))
 (:functions (total-cost) - number)
 (:action pick_center_place_center_n1_op0 :parameters (?a ?b - obj)
  :precondition (and (free ?a) (free ?b))
  :effect (and (on ?a ?b) (not (free ?b)) (increase (total-cost) 1))))
"""
DOMAIN_STRIPS = DOMAIN.replace(" :action-costs", "").replace(
    " (:functions (total-cost) - number)\n", "").replace(" (increase (total-cost) 1)", "")


class FakeStation:
    def __init__(self):
        self.truth: dict[str, np.ndarray] = {}
        self.types: dict[str, str] = {}

    def reset(self, scene):
        self.truth = {o.name: np.array(o.position, float) for o in scene.objects}
        self.types = {o.name: o.type for o in scene.objects}

    def settle(self, seconds):
        pass

    def object_states(self):
        return {n: ObjectState(n, self.types[n], p.copy()) for n, p in self.truth.items()}


class FakeBackend:
    """Exact perception of the fake station; pick/place puts the source on the target."""

    perception_seconds = 0.0

    def __init__(self):
        self.station = FakeStation()
        self.executed: list[Action] = []

    def reset(self, scene):
        self.station.reset(scene)

    def ground_truth_states(self):
        return self.station.object_states()

    def recording(self, path):
        return contextlib.nullcontext()

    def perceive(self, prior=None):
        items = sorted(self.station.truth.items(), key=lambda kv: tuple(kv[1]))
        objects = [PerceivedObject(f"p{i}", self.station.types[n], p.copy(), 0.0, 0.0,
                                   object_features(self.station.types[n], p, np.eye(3)),
                                   False, np.eye(3)) for i, (n, p) in enumerate(items)]
        contacts = {tuple(sorted((a.name, b.name))) for a in objects for b in objects
                    if a.name != b.name and _on(a.position, b.position)}
        return PerceivedScene(objects, contacts)

    def execute(self, action, before, lift=True):
        self.executed.append(action)
        # The belief names are the scene names (the agent names boxes after the file).
        target = self.station.truth[action.target]
        self.station.truth[action.source] = target + [0.0, 0.0, 0.05]
        return Execution("ok", None, self.perceive(before))


def _on(a, b) -> bool:
    return abs(a[2] - b[2] - 0.05) < 0.01 and np.linalg.norm(a[:2] - b[:2]) < 0.03


class OracleBundle:
    """A model bundle's data for the fake world: its one operator, for choosing offsets
    (abstraction/offsets.py; nothing to choose) and for reading plan steps."""

    domain, domain_strips = DOMAIN, DOMAIN_STRIPS
    operators = [LiftedOperator(0, "center", "center", 2, (("free", 0), ("free", 1)),
                                (("on", 0, 1),), (("free", 1),), 1)]
    planning = PlanningOperators(operators)
    planned, by_name = operators, {op.name: op for op in operators}
    path = "oracle"
    relevance_radius = CONTACT_TOLERANCE  # the paper's relevance: contact

    def domain_for(self, n_objects: int, costs: bool = True) -> str:
        return self.domain if costs else self.domain_strips


class OracleAbstraction(Abstraction):
    """The abstraction of a model that knows the fake world: p0 = free (nothing rests on
    it), r0(a, b) = a rests on b, read from the features' positions."""

    def __init__(self, force_mismatches: int = 0, hide_atoms: int = 0,
                 fail_replans: bool = False, bundle=None, forget_after: int | None = None):
        super().__init__(bundle or OracleBundle())
        self.force_mismatches = force_mismatches  # mismatches() reports one this many times
        self.hide_atoms = hide_atoms  # atoms() of what is seen is empty this many times
        self.forget_after = forget_after  # believed() is empty once after this many
        self.fail_replans = fail_replans  # plans after the first fail (a planner error)
        self.goal_contacts = []
        self.plans = 0

    def read(self, names, features, contacts=()):
        pos = np.asarray(features)[:, :3]
        n = len(names)
        on = np.array([[i != j and _on(pos[i], pos[j]) for j in range(n)] for i in range(n)])
        free = ~on.any(axis=0)
        state = SymbolicState(tuple(names), free[:, None], on[None])
        return Reading(state, np.zeros((n, 1), bool), np.zeros((1, n, n), bool),
                       {tuple(p) for p in contacts})

    def _atoms(self, reading, pairs=None):
        s = reading.state
        atoms = {Atom("free", o) for o, f in zip(s.objects, s.unary[:, 0], strict=True) if f}
        for i, a in enumerate(s.objects):
            for j, b in enumerate(s.objects):
                if s.relational[0, i, j] and (pairs is None or (a, b) in pairs):
                    atoms.add(Atom("on", a, b))
        return frozenset(atoms)

    def believed(self, reading):
        if self.forget_after is not None:
            self.forget_after -= 1
            if self.forget_after == -1:
                return frozenset()
        return super().believed(reading)

    def atoms(self, reading, guess=False, contacts_only=None):
        if self.hide_atoms > 0 and not guess:
            self.hide_atoms -= 1
            return frozenset(), frozenset()
        return self._atoms(reading), frozenset()

    def goal_atoms(self, goal):
        self.goal_contacts.append(set(goal.contacts))
        pairs = {p for a, b in goal.contacts for p in ((a, b), (b, a))}
        return frozenset(a for a in self._atoms(goal, pairs) if a[0] == "on")

    def plan(self, start, goal, planner="fd", budget=None, focus=True, penalties=None,
             unheld=frozenset()):
        self.plans += 1
        if self.fail_replans and self.plans > 1:
            return Plan("error", message="forced")
        return super().plan(start, goal, planner, budget, focus, penalties)

    def mismatches(self, after, step):
        if self.force_mismatches > 0:
            self.force_mismatches -= 1
            return [("free", "forced")]
        a, b = step.args
        return [] if ("on", a, b) in self._atoms(after) else [("on", a, b)]


def cube(name, x, y, z=0.025):
    return ObjectSpec(name, "cube", [x, y, z])


START = Scene([cube("a", 0.6, -0.2), cube("b", 0.8, 0.0), cube("c", 0.6, 0.25)])
GOAL = Scene([cube("a", 0.8, 0.0, 0.075), cube("b", 0.8, 0.0), cube("c", 0.6, 0.25)])


def solve(abstraction, monitor=True, max_replans=2, start=START, goal=GOAL, backend=None
          ) -> tuple[SolveResult, FakeBackend]:
    backend = backend or FakeBackend()
    config = SolveConfig("fd", 20.0, monitor, max_replans, refine=False, planning="symbolic")
    result = Agent(backend).solve(start, goal, abstraction, config)
    return result, backend


STEP = "(pick_center_place_center_n1_op0 a b)"


def test_solves_a_one_action_goal_and_reports_the_documented_json():
    result, backend = solve(OracleAbstraction())
    assert result.status == "success", result.to_json()
    assert [str(s) for s in result.plan] == [str(s) for s in result.executed] == [STEP]
    assert backend.executed == [Action("a", "center", "b", "center")]
    out = result.to_json()
    assert set(out) == {"status", "plan", "executed", "replans", "objects", "level",
                        "seconds", "nodes"}
    assert out["nodes"] == 2  # Fast Downward's A* on the one-action task: start and goal
    assert out["level"] == "symbolic"  # the level that found the first plan
    assert set(out["seconds"]) == {"perceive", "symbols", "plan", "execute", "total"}
    assert set(out["objects"]["a"]) == {"goal", "final", "final_true", "error_cm"}
    assert out["objects"]["a"]["error_cm"] == 0.0
    assert out["objects"]["a"]["final_true"] == [0.8, 0.0, 0.075]


def test_goal_contacts_are_the_perceived_goal_contacts_under_file_names():
    abstraction = OracleAbstraction()
    solve(abstraction)
    assert abstraction.goal_contacts[0] == {("a", "b")}  # c touches nothing in the goal


def test_the_bundle_writes_goal_relations_only_between_the_contacting_pairs():
    from pathlib import Path

    from drake_symplan.symbolic.bundle import ModelBundle
    from drake_symplan.symbolic.effect_operators import EFFECT

    bundle = ModelBundle(Path("hand-made"), None, [], EFFECT, {"n_unary": 1, "n_relations": 2},
                         {})
    names = ("a", "b", "c")
    every_bit = SymbolicState(names, np.ones((3, 1), bool), np.ones((2, 3, 3), bool))
    unsure = np.zeros((3, 1), bool), np.zeros((2, 3, 3), bool)
    start = Reading(every_bit, *unsure, contacts={("a", "b"), ("b", "c")})
    goal = Reading(every_bit, *unsure, contacts={("a", "b")})
    atoms = Abstraction(bundle).task(start, goal).goal
    # Unary symbols, and each object's contact degree in the goal's contacts (a, b).
    assert {a for a in atoms if len(a) == 2} == {("p0", "a"), ("p0", "b"), ("p0", "c"),
                                                 ("touching1", "a"), ("touching1", "b"),
                                                 ("touching0", "c")}
    assert {a for a in atoms if len(a) == 3} == {
        (f"r{k}", x, y) for k in range(2) for x, y in (("a", "b"), ("b", "a"))}


def test_a_mismatch_the_rest_of_the_plan_absorbs_costs_no_replan():
    # the step's predicted atoms are reported missing, but from what is seen the rest of
    # the plan (none, or c onto a) still reaches the goal
    result, _ = solve(OracleAbstraction(force_mismatches=1))
    assert result.replans == 0 and result.status == "success"
    tower = Scene([cube("a", 0.8, 0.0, 0.075), cube("b", 0.8, 0.0), cube("c", 0.8, 0.0, 0.125)])
    twice, _ = solve(OracleAbstraction(force_mismatches=5), goal=tower)
    assert twice.replans == 0 and len(twice.executed) == 2 and twice.status == "success"


def test_the_monitor_replans_where_the_rest_no_longer_reaches_the_goal():
    # after the first step nothing is believed (the third belief: the start's, its
    # plan's, then the monitor's): c onto a no longer applies, so the agent plans again
    tower = Scene([cube("a", 0.8, 0.0, 0.075), cube("b", 0.8, 0.0), cube("c", 0.8, 0.0, 0.125)])
    result, _ = solve(OracleAbstraction(force_mismatches=1, forget_after=2),
                      goal=tower)
    assert result.replans == 1 and result.status == "success"
    assert [str(s) for s in result.executed] == [STEP, "(pick_center_place_center_n1_op0 c a)"]
    open_loop, _ = solve(OracleAbstraction(force_mismatches=1), monitor=False)
    assert open_loop.replans == 0 and open_loop.status == "success"
    capped, _ = solve(OracleAbstraction(force_mismatches=1, forget_after=2),
                      max_replans=0, goal=tower)
    assert capped.replans == 0 and capped.status == "success"


class RefusingBackend(FakeBackend):
    """Refuses its first `refusals` actions (an unreachable pose), as the arm does."""

    def __init__(self, refusals: int):
        super().__init__()
        self.refusals, self.tried = refusals, 0

    def execute(self, action, before, lift=True):
        self.tried += 1
        if self.refusals > 0:
            self.refusals -= 1
            return Execution("infeasible", message="unreachable pose: grasp")
        return super().execute(action, before, lift)


def test_a_step_the_arm_refuses_is_planned_again_from_the_same_scene():
    result, backend = solve(OracleAbstraction(), backend=RefusingBackend(1))
    assert result.status == "success", result.to_json()
    # a refusal costs a plan, not one of the replans on a departure
    assert (backend.tried, result.refusals, result.replans) == (2, 1, 0)
    assert [str(s) for s in result.executed] == [STEP] and result.to_json()["refusals"] == 1
    # with no refusal left (two per object), or open loop, the refusal ends the solve
    limit = REFUSALS_PER_OBJECT * len(START.names)
    result, backend = solve(OracleAbstraction(), backend=RefusingBackend(100), max_replans=0)
    assert (result.status, result.refusals, backend.tried) == ("infeasible", limit, limit + 1)
    assert len(result.executed) == 1
    result, _ = solve(OracleAbstraction(), monitor=False, backend=RefusingBackend(1))
    assert (result.status, result.refusals) == ("infeasible", 0)


def test_a_failed_replan_lets_the_current_plan_run_on():
    tower = Scene([cube("a", 0.8, 0.0, 0.075), cube("b", 0.8, 0.0), cube("c", 0.8, 0.0, 0.125)])
    result, _ = solve(OracleAbstraction(force_mismatches=1, fail_replans=True,
                                        forget_after=2), goal=tower)
    assert result.replans == 1 and result.status == "success", result.to_json()
    assert [str(s) for s in result.executed] == [STEP, "(pick_center_place_center_n1_op0 c a)"]


def test_the_monitor_replans_when_the_goal_atoms_are_not_seen_at_the_end():
    result, _ = solve(OracleAbstraction(hide_atoms=1))
    assert result.replans == 1 and result.status == "success"
    assert len(result.executed) == 1  # the replan, from what is seen, is empty
    open_loop, _ = solve(OracleAbstraction(hide_atoms=1), monitor=False)
    assert open_loop.replans == 0


def test_no_plan_is_a_verdict_with_its_cause():
    # a and c both on b: once one is there, b is not free for the other.
    goal = Scene([cube("a", 0.8, 0.0, 0.075), cube("b", 0.8, 0.0), cube("c", 0.8, 0.0, 0.075)])
    result, backend = solve(OracleAbstraction(), goal=goal)
    assert result.status == "no_plan" and result.failure_cause == "no_plan"
    assert backend.executed == [] and result.symbolic_goal_reached is False
    assert result.to_json()["failure_cause"] == "no_plan"


def test_an_object_left_short_of_its_goal_is_an_execution_failure():
    class Nudging(FakeBackend):
        def execute(self, action, before, lift=True):
            super().execute(action, before, lift)
            self.station.truth["c"] = self.station.truth["c"] + [0.0, 0.08, 0.0]
            return Execution("ok", None, self.perceive(before))

    backend = Nudging()
    config = SolveConfig("fd", 20.0, monitor=False, refine=False, planning="symbolic")
    result = Agent(backend).solve(START, GOAL, OracleAbstraction(), config)
    assert result.status == "failure" and result.failure_cause == "execution"
    assert result.objects["c"]["error_cm"] == pytest.approx(8.0)
    assert result.symbolic_goal_reached  # the symbols cannot tell where c stands
    assert result.to_json()["symbolic_goal_reached"] is True


def test_boxes_are_named_after_the_nearest_file_object():
    seen = PerceivedScene([
        PerceivedObject("p0", "cube", np.array([0.61, 0.0, 0.025]), 0, 0, np.zeros(9), False,
                        np.eye(3)),
        PerceivedObject("p1", "cube", np.array([0.9, 0.3, 0.025]), 0, 0, np.zeros(9), False,
                        np.eye(3)),
    ], {("p0", "p1")})
    spec = Scene([cube("x", 0.6, 0.0), cube("y", 0.6, -0.3)])
    named = beliefs.name_by_file(seen, spec)
    assert named.scene.names == ["x"]
    assert named.lost == ["y"] and named.extra == ["p1"]
    assert named.scene.contacts == set()  # its partner was not named


def test_scene_pairs_must_hold_the_same_objects():
    with pytest.raises(beliefs.ScenePairError, match="unknown objects in the goal: \\['d'\\]"):
        beliefs.check_scene_pair(START, Scene([*GOAL.objects, cube("d", 0.5, 0.3)]))
    with pytest.raises(beliefs.ScenePairError, match="lacks start objects \\['c'\\]"):
        beliefs.check_scene_pair(START, Scene(GOAL.objects[:2]))
    longer = Scene([*GOAL.objects[:2], ObjectSpec("c", "long", [0.6, 0.25, 0.025])])
    with pytest.raises(beliefs.ScenePairError, match="change type"):
        beliefs.check_scene_pair(START, longer)


def fake_problem_set(root):
    """ROOT/set/p000: START to GOAL, one action away; returns ROOT/set."""
    import json

    from drake_symplan.world.scenes import save_scene

    folder = root / "set" / "p000"
    folder.mkdir(parents=True)
    save_scene(START, folder / "start.yaml")
    save_scene(GOAL, folder / "goal.yaml")
    (folder / "problem.json").write_text(json.dumps({"k": 1, "seed": 0, "n_objects": 3}))
    return root / "set"


def test_evaluate_planning_on_a_fake_world(tmp_path):
    from drake_symplan.evaluation.planning import evaluate_planning

    fake_problem_set(tmp_path)
    records = tmp_path / "results" / "records.jsonl"  # a folder not made yet
    kwargs = dict(agent=Agent(FakeBackend()), load=lambda run: OracleAbstraction(),
                  records_path=records)
    symbolic = SolveConfig(planning="symbolic")
    result = evaluate_planning([tmp_path / "oracle"], tmp_path, symbolic, **kwargs)
    summary = result["runs"][f"{tmp_path.name}/oracle"]
    assert summary["monitor"]["success"] == summary["open_loop"]["success"] == 1.0
    assert summary["monitor"]["by_k"]["1"]["plan_length_mean"] == 1.0
    assert summary["monitor"]["by_level"]["symbolic"]["problems"] == 1  # who found the plan
    assert len(records.read_text().splitlines()) == 2
    again = evaluate_planning([tmp_path / "oracle"], tmp_path, symbolic, **kwargs)  # resumes
    assert len(records.read_text().splitlines()) == 2
    assert again["runs"] == result["runs"]


def test_the_oracle_replays_a_recorded_problem(tmp_path):
    import json

    from drake_symplan.evaluation.planning import evaluate_planning
    from drake_symplan.world.scenes import save_scene

    folder = tmp_path / "set" / "p000"
    folder.mkdir(parents=True)
    save_scene(START, folder / "start.yaml")
    save_scene(GOAL, folder / "goal.yaml")
    actions = ["pick(a:center) place(b:center)"]
    (folder / "problem.json").write_text(json.dumps(
        {"k": 1, "seed": 0, "n_objects": 3, "actions": actions}))
    backend = FakeBackend()
    result = evaluate_planning([tmp_path / "oracle"], tmp_path,
                               SolveConfig(planning="oracle", monitor=False), monitor=(False,),
                               agent=Agent(backend), load=lambda run: OracleAbstraction())
    (record,) = result["records"]
    assert record["status"] == "success" and record["executed"] == 1
    assert backend.executed == [Action("a", "center", "b", "center")]
    assert result["settings"]["planning"] == "oracle"


@pytest.mark.slow
def test_eval_planning_on_local_workers_gives_the_in_process_records(tmp_path):
    from drake_symplan.evaluation.planning import evaluate_planning
    from drake_symplan.goals.problems import make_problems
    from drake_symplan.world.station import models_dir

    problems = tmp_path / "problems"
    make_problems(problems, 2, [1, 2], 3, 5, "hand")
    runs = [models_dir() / "learned"]
    here = evaluate_planning(runs, problems, robot="hand", monitor=(True,))
    records = tmp_path / "records.jsonl"
    pooled = evaluate_planning(runs, problems, robot="hand", monitor=(True,),
                               records_path=records, workers=2)

    def without_times(result):
        return [{k: v for k, v in r.items() if k != "seconds"} for r in result["records"]]

    assert len(without_times(pooled)) == 3
    assert without_times(pooled) == without_times(here)
    assert len(records.read_text().splitlines()) == 3


def test_a_records_file_cut_while_writing_resumes_without_the_cut_line(tmp_path):
    import json

    from drake_symplan.evaluation.planning import _resume

    records = tmp_path / "records.jsonl"
    done = {"run": "a/b", "monitor": True, "problem": "p000", "status": "success",
            "failure_cause": None, "success_true": True, "n_objects": 2, "k": 1,
            "plan_length": 1, "replans": 0, "seconds": {"plan": 0.1}, "error_cm": {}}
    records.write_text(json.dumps(done) + "\n" + '{"run": "a/b", "moni')
    told = []
    keys, found = _resume(records, told.append)
    assert keys == {("a/b", True, "p000")} and found == [done]
    assert records.read_text() == json.dumps(done) + "\n"
    assert told == [f"{records}: its incomplete last line (a solve cut off while it was "
                    "written) was dropped; resuming after its 1 record(s)"]
    assert _resume(records, told.append)[1] == [done] and len(told) == 1  # whole: no word
